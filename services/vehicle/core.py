"""The vehicle service core: plant + watchdog behind the ServiceCore contract, in the world's
current (common/world/current.py: the water's velocity at each RK4 stage's position and time).

The plant is vehicle.model's (plant.py): the unicycle with lags, which turns no tighter than
R_min whatever it is commanded (eq. (11)'s yaw-rate bound made physical with the R_min of eqs.
(19)-(20)), or the REMUS 100's 3-DOF dynamics, whose turn only its rudder bounds.

Time handling: the plant is integrated with RK4 on a fixed absolute grid of dt_internal_s
(cells [k dt, (k+1) dt]). Every accepted command becomes a command *schedule* in force from
its exact delivery time; a cell is integrated once it is complete, split only where the
applied (v, w) actually changes (a delivery that changes it, the start of a command's next
entry, a watchdog mode change). So a
command takes effect exactly when it is delivered, yet re-sending the same command at other
times leaves the trajectory bit-identical. States at off-grid output times are integrated
on a scratch copy. Everything depends only on the sequence of (deliver, step) calls.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping

from common.config.vehicle import VehicleConfig
from common.control import Applied, Schedule
from common.messages import Message, TruthState, VehicleStatus, VelocityCommand
from common.runtime.model.core import Delivery, Emit
from common.scalar import wrap_angle
from common.world.current import CurrentField
from services.vehicle.plant import PlantState, make_plant
from services.vehicle.watchdog import Verdict, Watchdog

log = logging.getLogger("tidelink.vehicle")

Clearance = Callable[[float, float, float], float]  # (x, y, t) -> signed clearance (eq. 12), m

# a remaining sub-step shorter than this is not integrated (it only absorbs float noise)
_MIN_STEP_S = 1e-12
# times this close to a grid point are on it (k * 0.05 and m * 0.01 differ in the last bits)
_GRID_TOL_S = 1e-9


class VehicleCore:
    """Simulated AUV: takes planner/cmd, publishes truth and status every period_s.

    In a fleet it also publishes its truth on "hull", for the other vehicles' sonars, but
    only at the steps whose truth a sonar scan will take: the last step before each scan of
    any of them (`hull_scans_s`: (period, first scan) of each, in mission seconds). A scan
    at t takes the newest truth sent before t, so the sonars see exactly what every step's
    truth would have shown them, at a tenth of the messages (20 Hz steps, 2 Hz scans): on a
    fleet of 16 those were most of the run's traffic (N (N - 1) deliveries a step).
    """

    def __init__(
        self,
        cfg: VehicleConfig,
        start: tuple[float, float, float],
        clearance: Clearance | None = None,
        *,
        current: CurrentField | None = None,
        t0: float = 0.0,
        commander: str | None = None,
        hull_scans_s: tuple[tuple[float, float], ...] = (),
        start_speed_mps: float = 0.0,
    ) -> None:
        self._cfg = cfg
        self._period_us = round(cfg.period_s * 1e6)
        self._hull_scans_us = tuple(
            sorted({(round(p * 1e6), round(first * 1e6)) for p, first in hull_scans_s})
        )
        # the water's velocity at (x, y, t); None in still water (the plant skips it)
        self._current = None if current is None or current.is_calm else current.velocity
        self._plant = make_plant(cfg, self._current)  # it moves in that water
        self._dt = cfg.dt_internal_s
        self._state: PlantState = self._plant.initial(
            float(start[0]), float(start[1]), float(start[2]), start_speed_mps
        )
        self._t = float(t0)  # committed time: the plant state is known up to here
        self._pieces: list[tuple[float, Schedule]] = [(self._t, Schedule(idle_v=start_speed_mps))]
        self._watchdog = Watchdog(
            cfg.watchdog,
            v_min=cfg.v_min_mps,
            v_max=cfg.v_max_mps,
            w_min=cfg.w_min_rps,
            w_max=cfg.w_max_rps,
            commander=commander,
            idle_v=start_speed_mps,
        )
        self._rejection_logged: dict[str, float] = {}  # reason -> mission time last logged
        self._clearance = clearance
        self.min_clearance_m = math.inf  # smallest clearance seen at any step
        self.collisions = 0  # steps at which the clearance was negative
        self._mode = ""  # the mode last published, and since when (a late-joining monitor
        self._mode_since = float(t0)  # learns the last mode change from any status)
        self.last_verdict: Verdict | None = None

    # -- ServiceCore -------------------------------------------------------------------------

    def deliver(self, d: Delivery) -> list[Emit]:
        """Integrate to the delivery time with the old command, then judge the new one."""
        msg = d.msg
        if not isinstance(msg, VelocityCommand):
            return []
        self._commit(d.t)
        before = self._watchdog.schedule
        self.last_verdict = verdict = self._watchdog.offer(
            d.t,
            msg.stamp,
            msg.v,
            msg.w,
            msg.source,
            step_s=msg.step_s,
            v_next=msg.v_next,
            w_next=msg.w_next,
        )
        if verdict != "applied":
            self._log_rejection(verdict, d.t, msg)
        after = self._watchdog.schedule
        if after is not before:
            start = max(d.t, self._t)  # a delivery in the plant's past takes effect now
            # a piece starting at or after this one would never be in force again (the last
            # listed that has started is): dropped, so the starts stay increasing (_windows)
            pieces = self._pieces
            while pieces and pieces[-1][0] >= start:
                pieces.pop()
            pieces.append((start, after))
        return []

    def resume(self, own: Mapping[str, Message], t: float) -> str | None:
        """Restarted at mission time t (Resumes): the hull is where the previous process last
        saw it, since the process is the vehicle's computer, not the vehicle. The plant
        starts from that truth (its integrator z at 0) at its stamp, with no command in
        force (IDLE) until this process accepts one, and is integrated on from there."""
        truth = own.get("truth")
        if not isinstance(truth, TruthState) or truth.stamp > t:
            return None
        self._state = self._plant.initial(
            truth.x, truth.y, truth.theta, truth.v, truth.sway, truth.w
        )
        self._t = truth.stamp
        self._pieces = [(self._t, Schedule())]
        return (
            f"the hull from its truth at t={truth.stamp:.2f} s: ({truth.x:.1f}, {truth.y:.1f}) "
            f"m, heading {math.degrees(truth.theta):.0f} deg, {truth.v:.2f} m/s"
        )

    def _log_rejection(self, reason: str, t: float, msg: VelocityCommand) -> None:
        """Say why a command was rejected: once per reason per mission second (a flood of
        hostile commands must not flood the log; the counts are in every status)."""
        last = self._rejection_logged.get(reason)
        if last is not None and t - last < 1.0:
            return
        self._rejection_logged[reason] = t
        count = self._watchdog.rejections[reason]
        log.warning(
            "t=%.2f s: rejected a command (%s): from %r, stamp %.3f s, seq %d (%d so far)",
            t,
            reason,
            msg.source,
            msg.stamp,
            msg.seq,
            count,
        )

    def step(self, t: float) -> list[Emit]:
        """Integrate to t and publish the true state and the vehicle status."""
        x, y, theta, v, sway, w = self._plant.motion(self.state_at(t))
        collided = False
        if self._clearance is not None:
            c = self._clearance(x, y, t)  # eq. (12): d = |x - a_k| - (r + r_k), < 0 = contact
            self.min_clearance_m = min(self.min_clearance_m, c)
            collided = c < 0.0
            self.collisions += int(collided)
        now = self.applied(t)
        wd = self._watchdog
        if now.mode != self._mode:
            self._mode, self._mode_since = now.mode, t
        cx, cy = (0.0, 0.0) if self._current is None else self._current(x, y, t)
        truth = TruthState(
            stamp=t,
            x=x,
            y=y,
            theta=wrap_angle(theta),
            v=v,
            w=w,
            collided=collided,
            sway=sway,
            current_x=cx,
            current_y=cy,
        )
        hull = [Emit(stream="hull", msg=truth)] if self._scanned_before_next_step(t) else []
        return [
            Emit(stream="truth", msg=truth),
            *hull,
            Emit(
                stream="status",
                msg=VehicleStatus(
                    stamp=t,
                    mode=now.mode,
                    mode_since=self._mode_since,
                    v_applied=now.v,
                    w_applied=now.w,
                    command_age=now.age_s,
                    commands_applied=wd.applied,
                    commands_rejected=wd.rejected,
                    commands_clamped=wd.clamped,
                    rejected_by_reason=wd.rejections,
                    delay_s=wd.delay.delay_s,
                    delay_jitter_s=wd.delay.jitter_s,
                    delay_samples=wd.delay.count,
                ),
            ),
        ]

    def _scanned_before_next_step(self, t: float) -> bool:
        """Whether another vehicle's sonar scans in (t, t + period_s]: after this step and
        no later than the next, so this step's truth is the newest it will hold."""
        t_us = round(t * 1e6)
        nxt = t_us + self._period_us
        return any(
            (first if t_us < first else first + ((t_us - first) // p + 1) * p) <= nxt
            for p, first in self._hull_scans_us
        )

    # -- plant ---------------------------------------------------------------------------------

    def state_at(self, t: float) -> PlantState:
        """The plant state at time t >= the committed time (commits every complete cell)."""
        self._commit(t)
        if t - self._t <= _GRID_TOL_S:
            return self._state
        return self._integrate(self._state, self._t, t)  # scratch: not committed

    def _cell(self, t: float) -> int:
        """Index k of the grid cell [k dt, (k+1) dt) that starts at or contains t."""
        k = math.floor(t / self._dt + 1e-9)
        if (k + 1) * self._dt <= t + _GRID_TOL_S:  # float noise: t is the end of cell k
            k += 1
        return k

    def _commit(self, t: float) -> None:
        """Integrate every grid cell that ends at or before t (within float noise)."""
        while True:
            k = self._cell(self._t)
            end = (k + 1) * self._dt
            if end > t + _GRID_TOL_S:
                return
            self._state = self._integrate(self._state, self._t, end)
            self._t = end
            # keep only the schedule in force from the new committed time on
            self._pieces = [(end, self._in_force(end))]

    def _in_force(self, t: float) -> Schedule:
        sched = self._pieces[0][1]
        for start, sc in self._pieces:
            if start <= t:
                sched = sc
        return sched

    def _applied_vw(self, t: float) -> tuple[float, float]:
        return self._in_force(t).vw_at(t)

    def _integrate(self, state: PlantState, t_a: float, t_b: float) -> PlantState:
        """RK4 over [t_a, t_b] inside one grid cell, split where the applied (v, w) changes."""
        # a change within float noise of the cell's end takes effect at the end, as a delivery
        # there does (_commit's tolerance): so a command's next entry acts exactly as the same
        # command delivered at that entry's start time would
        hi = t_b - _GRID_TOL_S
        if hi <= t_a:
            return self._rk4(state, t_a, t_b, self._applied_vw(t_a))
        seg_a, cur = t_a, None
        for lo, end, sc in self._windows(t_a, hi):
            # the schedule's constant pieces, (v, w) = vw_at(their start): a piece whose (v, w)
            # is the one applied already changes nothing (a cut only where it changes)
            s = lo
            for e, v, w in sc.pieces_between(lo, end):
                if cur is None:
                    cur = (v, w)
                elif (v, w) != cur:
                    state = self._rk4(state, seg_a, s, cur)
                    seg_a, cur = s, (v, w)
                s = e
        assert cur is not None  # (t_a < hi: at least one window, of at least one piece)
        return self._rk4(state, seg_a, t_b, cur)

    def _windows(self, t_a: float, t_b: float) -> list[tuple[float, float, Schedule]]:
        """The schedules in force over [t_a, t_b) as (from, until, schedule) in turn: each
        piece's from its start (increasing) to the next's, the first's also before its start
        (_in_force's rule)."""
        pieces = self._pieces
        if len(pieces) == 1:
            return [(t_a, t_b, pieces[0][1])]
        out: list[tuple[float, float, Schedule]] = []
        for i, (start, sc) in enumerate(pieces):
            until = pieces[i + 1][0] if i + 1 < len(pieces) else t_b
            lo = start if i and start > t_a else t_a
            if until > t_b:
                until = t_b
            if lo < until:
                out.append((lo, until, sc))
        return out

    def _rk4(
        self, state: PlantState, t_a: float, t_b: float, vw: tuple[float, float]
    ) -> PlantState:
        h = t_b - t_a
        if h < _MIN_STEP_S:
            return state
        return self._plant.step(state, h, t_a, vw[0], vw[1])

    def applied(self, t: float) -> Applied:
        """Mode and command the watchdog applies at time t."""
        return self._watchdog.command(t)

    @property
    def time(self) -> float:
        """The plant's committed time (s)."""
        return self._t

    @property
    def pose(self) -> tuple[float, float, float, float, float]:
        """True (x, y, theta, v, w) at the committed time; theta unwrapped (continuous)."""
        x, y, theta, v, _, w = self._plant.motion(self._state)
        return x, y, theta, v, w

    @property
    def watchdog(self) -> Watchdog:
        """The command watchdog (for its counters)."""
        return self._watchdog

    @property
    def thrust_n(self) -> float:
        """Thrust the speed loop produces at the committed time (N)."""
        return self._plant.thrust_n(self._state, self._applied_vw(self._t)[0])

    @property
    def drag_n(self) -> float:
        """Hydrodynamic surge resistance at the committed time (N; eq. (14) for the unicycle)."""
        return self._plant.drag_n(self._state)
