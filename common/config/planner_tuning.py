"""The planner's verification and fallback tuning: rollouts before adoption, stepping aside.

These were module constants of services/planner/safety/rollout.py and services/planner/evade.py;
here a sweep can set them (`--set planner.tuning.rollout_cushion_m=0.2`) and the loader
validates them with the rest of the scenario. The defaults are the values the missions were
measured with (docs/notes/planner-flight-keeps-rho0-plus-cushion.md, planner-flight-detour.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from common.config.checks import fraction, int_range, nonneg, positive


@dataclass(frozen=True, kw_only=True)
class PlannerTuning:
    """Tunables of plan-and-verify (a plan's rollout on the response model before it is
    adopted) and of stepping aside from a moving obstacle's way."""

    # --- rollout (services/planner/safety/rollout.py)
    rollout_max_s: float = 90.0  # a rollout ends at the path's end, or after this long (s)
    # a rollout must keep rho0 + this (the model knows no current and no estimation error);
    # the same cushion widens the margin a plan is made again with, past its tracking error
    rollout_cushion_m: float = 0.1
    # a rollout starts at the estimate, which is off the truth by about its position standard
    # deviation: the cushion it keeps widens by this many of them (the estimate's larger axis)
    rollout_start_sigmas: float = 1.0
    # moving obstacles count over a rollout's first seconds only (their prediction a minute
    # ahead is a guess); a fleet vehicle's broadcast route counts throughout
    rollout_moving_s: float = 10.0
    # a plan whose rollout touches an obstacle within this long (s) is never adopted
    # (services/planner/asking.py); farther on, the replans on the way judge it
    contact_horizon_s: float = 30.0
    rollout_curvature_factor: float = 0.9  # the second plan aims its curvature this much lower
    rollout_detour_m: float = 0.5  # the third avoids a disc this wide where it came nearest
    rollout_slow_factor: float = 0.5  # the fourth is made and rolled out at this share of speed
    arrived_m: float = 0.5  # a rollout this near the path's end, slower than arrived_mps, is over
    arrived_mps: float = 0.05
    # --- stepping aside (services/planner/evade.py)
    evade_s: float = 10.0  # how far ahead a moving obstacle's approach is weighed (s)
    evade_length_step_m: float = 1.0  # the ways aside end every this far along
    evade_shortlist: int = 6  # of the swept ways, this many (the best) are rolled out
    evade_gain_m: float = 0.1  # a way aside is taken if it clears this much more than holding
    # a recovery into rho0 waits while the vehicle, holding, is faster than this share of cruise
    hold_first_factor: float = 0.25
    # --- without a plan, in a current (services/planner/stopping.py)
    # a vehicle gives way (drifts back) from an obstacle upstream nearer than its margins and
    # this many turning radii: kept nearer, it faces an obstacle it has no room to turn from
    give_way_room_r: float = 1.0

    def __post_init__(self) -> None:
        for name in (
            "rollout_max_s",
            "rollout_moving_s",
            "contact_horizon_s",
            "arrived_m",
            "arrived_mps",
            "evade_s",
            "evade_length_step_m",
        ):
            positive(name, getattr(self, name))
        for name in (
            "rollout_cushion_m",
            "rollout_start_sigmas",
            "rollout_detour_m",
            "evade_gain_m",
            "give_way_room_r",
        ):
            nonneg(name, getattr(self, name))
        for name in ("rollout_curvature_factor", "rollout_slow_factor", "hold_first_factor"):
            fraction(name, getattr(self, name))
        int_range("evade_shortlist", self.evade_shortlist, 1, 100)
