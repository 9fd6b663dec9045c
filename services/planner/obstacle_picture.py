"""What the planner knows of the obstacles: the chart, the newest tracks, other vehicles' intents.

Static obstacles come from the chart (the scenario's world); moving ones from the estimator's
tracks, predicted with their velocity and acceleration (paper §2), and in a fleet from the
other vehicles' broadcast intents, which replace their sonar tracks (safety/intent.py).
"""

from __future__ import annotations

import logging

from common.config.world import WorldConfig
from common.guard import Plausibility, Reason, first_reason
from common.messages import ObstacleTracks
from common.world import ObstacleState
from services.planner.result import Obstacles
from services.planner.safety.intent import FleetIntents

log = logging.getLogger("tidelink.planner")


def judge_tracks(j: Plausibility, m: ObstacleTracks, now: float) -> Reason | None:
    """Why a set of tracks is implausible (stamp, count, each track's pose, speed, size)."""
    why = first_reason(j.stamp(m.stamp, now), j.items(len(m.tracks)))
    for k in m.tracks:
        if why is not None:
            break
        why = first_reason(
            j.position(k.x, k.y), j.speed(k.vx, k.vy), j.accel(k.ax, k.ay), j.length(k.radius)
        )
    return why


class ObstaclePicture:
    """The obstacles a plan is made among, at any time: the chart's, the newest plausible
    tracks (by stamp) and, in a fleet, the other vehicles' intents."""

    def __init__(
        self, world: WorldConfig, intents: FleetIntents | None, first_plan_wait_s: float
    ) -> None:
        self.world = world
        self.intents = intents
        self.first_plan_wait_s = first_plan_wait_s
        self.static_ids = frozenset(c.id for c in world.circles) | frozenset(
            p.id for p in world.polygons
        )
        self.tracks: ObstacleTracks | None = None

    def take(self, m: ObstacleTracks) -> None:
        """Keep tracks judged plausible if they are the newest by stamp."""
        if self.tracks is None or m.stamp >= self.tracks.stamp:
            self.tracks = m

    def at(self, t: float) -> Obstacles:
        """The obstacles as they will be at t (s): moving ones predicted to then."""
        moving: list[ObstacleState] = []
        covered: frozenset[int] = frozenset()
        if self.intents is not None:  # other vehicles' intents replace their sonar tracks
            intents, covered = self.intents.obstacles(t)
            moving.extend(intents)
        if self.tracks is not None:
            dt = max(0.0, t - self.tracks.stamp)  # predict the tracks to now (constant accel.)
            for k in self.tracks.tracks:
                if k.id in self.static_ids or k.id in covered:
                    continue  # charted static obstacles are planned from the chart
                moving.append(ObstacleState.of_track(k).advanced(dt))
        return Obstacles(
            circles=self.world.circles, polygons=self.world.polygons, moving=tuple(moving)
        )

    def awaiting_first(self, t: float) -> bool:
        """Should the first plan wait longer for the first obstacle tracks?

        The estimator publishes tracks every period from the start, empty until it has fused
        a sonar scan that detected something: a track exists only after a detection. So the
        tracks are "in" once a message holding at least one track has arrived (charted static
        obstacles count: the scan that saw them could see a moving one in view too). An empty
        message cannot tell "no scan yet" from "nothing in view", so the wait is bounded by
        mission time first_plan_wait_s: then the planner plans with what it has (a field with
        nothing in sonar range still starts) and says why. A planner restarted later in the
        mission (its estimator has long fused scans) plans at once.
        """
        if self.tracks is not None and self.tracks.tracks:
            return False
        if t < self.first_plan_wait_s:
            return True
        # reached once: the plan is made in this step
        log.info(
            "t=%.2f s: first plan without obstacle tracks (none by planner.first_plan_wait_s "
            "= %.2f s): %s",
            t,
            self.first_plan_wait_s,
            "no tracks message arrived"
            if self.tracks is None
            else f"the newest tracks (stamp {self.tracks.stamp:.2f} s) hold none: "
            "no scan fused yet, or nothing in sonar range",
        )
        return False
