"""Planner service: a NURBS path within R_min around the obstacles, tracked over the network.

The pipeline, stage by stage, with the sub-package that holds each (paper equations):

    PlanRequest         result.py: start, goal, area, obstacles, vehicle radius, R_min
        |
    cost map            search/costmap.py      eq. (5)-(6) potential, eq. (17) smoothing;
        |               search/prediction.py   moving obstacles blocked where they will be
    graph search        search/graph.py        eq. (15)-(16) shortest path on the grid
        |
    prune               search/prune.py        any-angle waypoints
        |
    NURBS fit           shaping/fit.py         control polygon, eq. (10) boundary tangents
        |
    refine              shaping/refine.py      eq. (8)-(9) penalties, eq. (19) turning cost
        |
    check               shaping/check.py       eq. (12)-(13) clearance, eq. (20) curvature
        |                                      (plan.py runs these stages: a PlanResult)
    planned path        geometry/planned_path.py, shaping/path_arc_reference.py (on s)
        |
    controller          services/control/      NURBS tracker, Backstepping, immune fuzzy PID
        |
    command sequence    services/control/      predicted over the measured delays, sent

    Layers, one way down: geometry/ (clearance.py, the exact distances every stage uses;
    nurbs_curve.py and planned_path.py, the curve and its arc-length table), then search/,
    shaping/, plan.py and the safety monitor (safety/):
    recover.py and escape.py, ways out near or in contact; rollout.py, a plan flown on the
    response model before it is adopted; intent.py, the other vehicles of a fleet as
    obstacles with known trajectories. evade.py, stepping aside or holding first, plans again.
    core.py is the service core, a thin host: it decides (replan.py), asks (asking.py),
    adopts (adoption.py: decline.py's rules, path_message.py) and sends; stopping.py says
    where a stopping vehicle stays; fleet.py exchanges intents with a fleet's other vehicles.
    reasons.py: the codes each result carries, the strategy that made it and those rejected.

Functional API of the planning pipeline (pure: no clock, no randomness, no I/O), each name
from its own module (plan.py, result.py, shaping/): this package imports nothing itself, so
that a reader of one module (the metrics of a run read a path's curve) does not load the whole
planner with scipy's graph and image modules.

    req = PlanRequest(start=..., goal=..., obstacles=..., vehicle_radius_m=vehicle.radius_m)
    result = plan_path(req, PlannerConfig())
    if result.ok:
        path = PlannedPath(result.curve())  # on the curve parameter u, with s(u) and u(s)
        ref = PathArcReference(path, v_ref)  # on arc length s: what a controller follows

Obstacles use the world's types (common.config.world circles and polygons, common.world's
ObstacleState for moving ones); the area is the scenario's AreaConfig.
"""
