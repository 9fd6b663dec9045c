"""A plan's reason codes: the closed vocabulary of the strategies that make a plan, or of why none.

A request runs a cascade of strategies (plan.py, rollout.py, evade.py, asking.py). Each
PlanResult names the one that made it (`strategy`: for a NO_PATH, why there is none) and those
that ran before it and did not give it (`rejected`, in the order they ran; a strategy that
found nothing to try counts as run). A plan made by a strategy that runs the pipeline again
(a recovery, a plan made again) is named by that strategy alone: the pipeline's own codes
inside it are not kept. The code travels in the path message (PathMsg.strategy, .rejected)
to metrics.json (plan_strategies, plan_strategies_rejected), `tidelink monitor` and Foxglove
(/plot/path.strategy, .rejected: services/foxglove/view.py).
"""

from __future__ import annotations

from typing import Literal, get_args

Strategy = Literal[
    # --- a plan made (status OK), by the strategy that made it
    "searched",  # search the grid, shape a curve on the route (plan.py): the first search
    "searched_static",  # ... again on the static field: moving obstacles' discs walled it off
    "searched_passing",  # ... again, each moving obstacle blocked where a curve passed it
    "turned_first",  # turn away on an arc, then plan (recover.py turn_then_plan)
    "escaped_first",  # a way out of contact, the margin or beyond the area first (leave_then_plan)
    "came_about_first",  # come about across the area's edge first (come_about_then_plan)
    "heading_freed",  # near the goal, to it with its heading free: none joins it (plan.py)
    "partway",  # a plan part of the way along the searched route (safety/partway.py)
    "remade_wider",  # made again wider: the first one's rollout broke rho0 or missed the goal
    "remade_around",  # ... around where that rollout came nearest a static obstacle
    "remade_slower",  # ... for a lower speed (safety/rollout.py)
    "hull_turns",  # within the hull's own R_min: none within R_min over ground (asking.py)
    "stepped_aside",  # a way aside, out of a moving obstacle's way, short of the goal (evade.py)
    # --- no plan (status NO_PATH), by why
    "goal_refused",  # the goal is outside the area, at the start or within rho0 of an obstacle
    "stuck",  # the start is in contact or outside the area, and no way out is clear
    "no_route",  # no route on the grid: obstacles inflated by r + rho0 wall the goal off
    "no_curve",  # no curve within R_min follows the route, nor does any recovery help
    "held_first",  # only a recovery into rho0 while under way: hold first (evade.py)
    "declined_contact",  # its rollout has the hull touch an obstacle soon: hold (asking.py)
]

STRATEGIES: tuple[Strategy, ...] = get_args(Strategy)

# the statistics counter of the plans declined, the path in force kept (adoption.py; the
# metric of that name), and its prefix by decline rule ("plans_declined.<code>")
PLANS_DECLINED = "plans_declined"
