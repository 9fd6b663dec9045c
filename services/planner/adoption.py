"""Adopting a plan made, or declining it and keeping the path in force (decline.py)."""

from __future__ import annotations

from common.config.planner import PlannerConfig
from common.messages import PathMsg
from services.control.command.link import Prediction
from services.control.loop import CommandLoop
from services.planner.asking import Asked
from services.planner.decline import decline
from services.planner.path_message import path_message
from services.planner.reasons import PLANS_DECLINED
from services.planner.replan import ReplanPolicy
from services.planner.result import PlanResult, PlanStatus, Pose2D
from services.planner.shaping.path_arc_reference import PathArcReference


class Adoption:
    """Settles each plan made (`settle`): declined by a rule of decline.py, the path in force
    kept, or put in force on `loop` and told to `policy`, as the path message sent."""

    def __init__(
        self,
        cfg: PlannerConfig,
        loop: CommandLoop[PathArcReference],
        policy: ReplanPolicy,
        goal: Pose2D,
        *,
        cruise_speed_mps: float,
    ) -> None:
        self.cfg, self.loop, self.policy, self.goal = cfg, loop, policy, goal
        self.cruise_speed_mps = cruise_speed_mps
        self.last_result: PlanResult | None = None  # the plan adopted last
        # the status of the last path published and since when it has held without a break:
        # every PathMsg carries it, so a NO_PATH that persists is visible from any one message
        self.path_status: PlanStatus | None = None
        self.status_since = 0.0
        self.declined = 0  # precautionary plans (or NO_PATHs stepping aside) declined
        self.declined_by: dict[str, int] = {}  # ... by reason code (decline.py)

    @property
    def counters(self) -> dict[str, int]:
        """The plans declined (PLANS_DECLINED), and by reason code ("plans_declined.<code>")."""
        by = {f"{PLANS_DECLINED}.{code}": n for code, n in self.declined_by.items()}
        return {PLANS_DECLINED: self.declined, **by}

    def speed_of(self, result: PlanResult) -> float:
        """The speed a plan is followed at: the one it was made for (rollout.py), else cruise."""
        return self.cruise_speed_mps if result.v_ref_mps is None else result.v_ref_mps

    def settle(self, t: float, pred: Prediction, asked: Asked, made: PlanResult) -> PathMsg | None:
        """The plan `made` for `asked`, there at step t (s) with the vehicle predicted `pred`:
        its path message, stamped t, once it is in force; None when it is declined."""
        declined = decline(
            t,
            pred,
            asked,
            made,
            v_ref=self.speed_of(made),
            policy=self.policy,
            last=self.last_result,
            has_path=self.loop.ref is not None,
            arrived_m=self.cfg.tuning.arrived_m,
            safe_for_s=self._safe_for_s(),
        )
        if declined is None:
            return self._adopt(t, asked, made)
        self.declined += 1
        self.declined_by[declined.code] = self.declined_by.get(declined.code, 0) + 1
        return None

    def _safe_for_s(self) -> float:
        """How long the path in force can be followed before it stops (s): short of a conflict
        found ahead (core.py), else at its end; 0 without one."""
        ref = self.loop.ref
        if ref is None:
            return 0.0
        return max(ref.stop_s - self.policy.s_now, 0.0) / ref.v_ref

    def _adopt(self, t: float, asked: Asked, result: PlanResult) -> PathMsg:
        """Put the plan made in force; the path message is stamped t, when it is sent."""
        self.policy.on_planned(
            asked.t_plan, result, self.goal, asked.obstacles, asked.current, asked.pace
        )
        self.last_result = result
        self.loop.path_id += 1
        if result.status != self.path_status:
            self.path_status, self.status_since = result.status, t
        v_ref = self.speed_of(result)
        self.loop.take(PathArcReference(result.planned_path(), v_ref) if result.ok else None)
        return path_message(
            result,
            stamp=t,
            path_id=self.loop.path_id,
            status_since=self.status_since,
            why=asked.why,
            v_ref=v_ref,
        )
