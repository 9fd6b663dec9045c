"""The sensor core: samples the vehicle's true state into navigation (fixes, or an AUV's
odometry and USBL fixes) and obstacle scans."""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping

import numpy as np

from common.config.sensor import SensorConfig
from common.guard import Plausibility, RateLimitedLog, Reason, first_reason
from common.guard.rejects import warn_rejected
from common.messages import PositionFix, TruthState
from common.runtime.model.core import Delivery, Emit
from common.world import World
from common.world.model import ObstacleState
from services.sensor.models import (
    FIX_DRAWS,
    NAV_DRAWS,
    ODOMETRY_DRAWS,
    SCAN_DRAWS,
    nav_fix,
    odometry,
    position_fix,
    scan,
)

log = logging.getLogger("tidelink.sensor")


class SensorCore:
    """Emits "nav" at nav_rate_hz and "obstacles" at obstacle_rate_hz from vehicle/truth; with
    navigation = "dvl_usbl", "odometry" at nav_rate_hz and "fix" every few seconds instead of
    "nav" (the DVL's bottom lock comes and goes as a two-state Markov chain, the AHRS's bias
    is drawn once).

    Each measurement samples the newest truth received and carries its stamp (the sampling
    time), so transport delay on vehicle/truth becomes measurement latency. A stream skips a
    step when the truth has not advanced since its last sample (no sample is taken twice).

    In a fleet the other vehicles are obstacles like the world's moving ones: `others` maps
    each other vehicle's truth source to (its obstacle id, its hull radius); the sonar sees
    it where its newest truth, carried forward at its speed, puts it at the scan's time.
    """

    def __init__(
        self,
        cfg: SensorConfig,
        world: World,
        rng: np.random.Generator,
        *,
        own: str = "vehicle",
        others: Mapping[str, tuple[int, float]] | None = None,
        phase_s: float = 0.0,
    ) -> None:
        self.cfg = cfg
        self.world = world
        self._rng = rng
        self._own = own
        self._others = dict(others or {})
        self._other_truth: dict[str, TruthState] = {}
        base = cfg.base_rate_hz
        self._period_s = cfg.period_s
        self._phase_s = phase_s  # it steps at phase_s + k period_s (a fleet vehicle's phase)
        self._nav_every = round(base / cfg.nav_rate_hz)
        self._obs_every = cfg.scan_every
        self._truth: TruthState | None = None
        self._last_nav = -np.inf
        self._last_scan = -np.inf
        self.stale_skips = 0  # scheduled samples skipped because the truth had not advanced
        self._judge = Plausibility.of_area(world.cfg.area)
        self._rejects = RateLimitedLog(log)
        self._auv = cfg.navigation == "dvl_usbl"
        # an AUV's navigation (drawn only then: a fix-navigated run's draws are unchanged)
        self._bias_rad = cfg.ahrs_bias_std_rad * float(rng.standard_normal()) if self._auv else 0.0
        self._locked = True  # the DVL's bottom lock
        self._next_fix_t = 0.0  # the first USBL fix as soon as there is a truth
        self._last_fix = -np.inf
        self.dvl_dropouts = 0  # bottom lock lost (times)

    def deliver(self, d: Delivery) -> list[Emit]:
        msg = d.msg
        if not isinstance(msg, TruthState):
            return []
        why = self._judge_truth(msg, d.t)
        if why is not None:
            warn_rejected(self._rejects, "truth", why, d.t, msg)
        elif d.source in self._others:
            seen = self._other_truth.get(d.source)
            if seen is None or msg.stamp > seen.stamp:
                self._other_truth[d.source] = msg
        elif d.source != self._own:
            return []  # the dataflow wires no other truth; never one's own pose from elsewhere
        elif self._truth is None or msg.stamp > self._truth.stamp:
            self._truth = msg
        return []

    def _navigation(self, truth: TruthState) -> Emit:
        """The navigation sample of this step: a fix, or the AHRS + DVL odometry."""
        if not self._auv:
            z = self._rng.standard_normal(NAV_DRAWS)
            return Emit(stream="nav", msg=nav_fix(truth, self.cfg, z))
        cfg = self.cfg
        dt = 1.0 / cfg.nav_rate_hz
        u = float(self._rng.random())  # bottom lock: lost at a rate, regained after a mean
        if self._locked and u < cfg.dvl_dropout_per_s * dt:
            self._locked = False
            self.dvl_dropouts += 1
        elif not self._locked and u < dt / cfg.dvl_dropout_mean_s:
            self._locked = True
        z = self._rng.standard_normal(ODOMETRY_DRAWS)
        return Emit(stream="odometry", msg=odometry(truth, cfg, self._bias_rad, self._locked, z))

    def _usbl(self, truth: TruthState) -> PositionFix:
        """A USBL fix of the newest truth; the next one a uniform period later."""
        cfg = self.cfg
        z = np.concatenate([self._rng.standard_normal(FIX_DRAWS - 1), self._rng.random(1)])
        gap = cfg.usbl_period_min_s + (cfg.usbl_period_max_s - cfg.usbl_period_min_s) * float(
            self._rng.random()
        )
        self._next_fix_t = truth.stamp + gap
        self._last_fix = truth.stamp
        return position_fix(truth, cfg, z)

    def _vehicles_at(self, t: float) -> tuple[ObstacleState, ...]:
        """The other vehicles of a fleet at time t, as moving obstacles, by id."""
        out = []
        for src, (oid, radius) in sorted(self._others.items(), key=lambda kv: kv[1][0]):
            q = self._other_truth.get(src)
            if q is None:
                continue
            vx, vy = q.v * math.cos(q.theta), q.v * math.sin(q.theta)
            dt = t - q.stamp
            at = (q.x + vx * dt, q.y + vy * dt)
            out.append(ObstacleState.of_motion(oid, radius, at, (vx, vy), (0.0, 0.0)))
        return tuple(out)

    def _judge_truth(self, m: TruthState, now: float) -> Reason | None:
        j = self._judge
        return first_reason(
            j.stamp(m.stamp, now), j.position(m.x, m.y), j.angle(m.theta), j.speed(m.v), j.rate(m.w)
        )

    @property
    def inputs_rejected(self) -> dict[str, int]:
        """Truth messages rejected, by 'truth.<reason>'."""
        return dict(self._rejects.counts)

    def step(self, t: float) -> list[Emit]:
        # integer tick index from the runtime clock: no float accumulation over a long run
        k = round((t - self._phase_s) / self._period_s)
        truth = self._truth
        out: list[Emit] = []
        if truth is None:
            return out
        if k % self._nav_every == 0:
            if truth.stamp > self._last_nav:
                out.append(self._navigation(truth))
                self._last_nav = truth.stamp
            else:
                self.stale_skips += 1
        if self._auv and t >= self._next_fix_t and truth.stamp > self._last_fix:
            out.append(Emit(stream="fix", msg=self._usbl(truth)))
        if k % self._obs_every == 0:
            if truth.stamp > self._last_scan:
                obstacles = self.world.obstacles_at(truth.stamp) + self._vehicles_at(truth.stamp)
                n = len(obstacles)
                u = self._rng.random(n)
                z = self._rng.standard_normal((n, SCAN_DRAWS))
                out.append(Emit(stream="obstacles", msg=scan(obstacles, truth, self.cfg, u, z)))
                self._last_scan = truth.stamp
            else:
                self.stale_skips += 1
        return out
