"""Load campaigns: simulated ones with hidden effects, and the design of the next one.

* :mod:`~rfsw_plan.validation.campaign.simulation`: synthetic campaigns whose truth model hides
  effects (``simulate-campaign``);
* :mod:`~rfsw_plan.validation.campaign.design`: what to measure next so that the named effects
  are identifiable (``design-campaign``).
"""
