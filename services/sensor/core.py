"""The sensor core: samples the vehicle's true state into navigation fixes and obstacle scans."""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping

import numpy as np

from common.config.sensor import SensorConfig
from common.guard import Plausibility, RateLimitedLog, Reason, first_reason
from common.guard.rejects import warn_rejected
from common.messages import TruthState
from common.runtime.model.core import Delivery, Emit
from common.world import World
from common.world.model import ObstacleState
from services.sensor.models import NAV_DRAWS, SCAN_DRAWS, nav_fix, scan

log = logging.getLogger("tidelink.sensor")


class SensorCore:
    """Emits "nav" at nav_rate_hz and "obstacles" at obstacle_rate_hz from vehicle/truth.

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
                z = self._rng.standard_normal(NAV_DRAWS)
                out.append(Emit(stream="nav", msg=nav_fix(truth, self.cfg, z)))
                self._last_nav = truth.stamp
            else:
                self.stale_skips += 1
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
