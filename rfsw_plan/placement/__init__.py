"""Where to put the part: stiffness maps over placements and placement optimisation.

* :mod:`~rfsw_plan.placement.geometry`: placements (table-plane position, yaw, height) and how
  they move a task;
* :mod:`~rfsw_plan.placement.ik`: vectorised IK over placements x waypoints;
* :mod:`~rfsw_plan.placement.map`: the indices at every placement (:func:`compute_map`);
* :mod:`~rfsw_plan.placement.region`: default region and reachable extent;
* :mod:`~rfsw_plan.placement.session`: a map over a user request with the input checks;
* :mod:`~rfsw_plan.placement.optimise`: screening plus full plans of the best candidates on any
  ``concurrent.futures.Executor`` (:func:`place`);
* :mod:`~rfsw_plan.placement.files`, :mod:`~rfsw_plan.placement.plots`: outputs.
"""

from rfsw_plan.placement.geometry import Placement, PlacementGrid, place_task
from rfsw_plan.placement.map import MapInput, PlacementMap, compute_map, map_input

__all__ = [
    "MapInput",
    "Placement",
    "PlacementGrid",
    "PlacementMap",
    "compute_map",
    "map_input",
    "place_task",
]
