"""Model against measurement: simulated campaigns, residuals, diagnosis and reports."""
