"""Command-line interface (``rfsw-plan``)."""
