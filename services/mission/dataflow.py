"""The AUV mission's dataflow, declared once: four services, their streams and every link.

    sensor    --nav, obstacles-->  estimator  --state, tracks-->  planner
              (sensor.navigation = "dvl_usbl": odometry and fix instead of nav)
    planner   --cmd------------->  vehicle    --truth---------->  sensor
    vehicle   --status---------->  planner    (the one-way delay measured on commands)
    with controller.placement = "onboard" a fifth service, on the vehicle's node:
    planner   --path------------>  tracker    --cmd------------>  vehicle (status -> tracker)
    tracker   --ack------------->  planner    (the path it follows, on each path received)
    (planner/path and every <service>/stats are published for the record, monitors and
     metrics; no service reads them)

Each service's core is built by a factory with one signature, `(ctx: CoreContext) -> core`;
the factory takes from the scenario only what its core needs.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import TYPE_CHECKING

from common.config.network import link_name, profile_for
from common.config.scenario import Scenario
from common.messages import (
    NavFix,
    ObstacleDetections,
    ObstacleTracks,
    Odometry,
    PathAck,
    PathMsg,
    PositionFix,
    StateEstimate,
    TruthState,
    VehicleStatus,
    VelocityCommand,
)
from common.runtime.model.core import QueuePolicy
from common.runtime.model.dataflow import CoreContext, Dataflow, Input, Output, Service
from common.world import World
from common.world.current import CurrentField

if TYPE_CHECKING:
    from services.control.loop import CommandLoop
    from services.estimator.core import EstimatorCore
    from services.planner.core import PlannerCore
    from services.planner.shaping.path_arc_reference import PathArcReference
    from services.sensor.core import SensorCore
    from services.tracker.core import TrackerCore
    from services.vehicle.core import VehicleCore

# Each factory imports its own core: a service process then loads only its own service's
# libraries (filterpy and scipy.stats for the estimator alone, scipy's graph and optimizer
# for the planner), which saves CPU in every process at every launch.

NEWEST = QueuePolicy.NEWEST
# the delay the vehicle measures on commands, for whoever commands (delay compensation,
# docs/notes/0007-command-sequences.md). 20 Hz: room for 12 s of them in flight (the
# commander keeps only the newest)
STATUS = Input(
    source="vehicle", stream="status", msg_type=VehicleStatus, policy=NEWEST, max_queued=256
)


def commander(s: Scenario) -> str:
    """The one service whose commands the vehicle applies: the planner, or the onboard
    tracker with controller.placement = "onboard"."""
    return "tracker" if s.controller.placement == "onboard" else "planner"


def auv_dataflow(s: Scenario) -> Dataflow:
    """sensor -> estimator -> planner (+controller) -> vehicle -> (truth) -> sensor; with
    the controller onboard: planner --path--> tracker (+controller) --cmd--> vehicle."""
    onboard = commander(s) == "tracker"
    return Dataflow.declare(*_services(s), *((_tracker(s),) if onboard else ()))


def _tracker(s: Scenario) -> Service:
    return Service(
        name="tracker",
        factory=make_tracker,
        period_s=s.planner.period_s,  # the controller's period, as in the planner
        offset_s=s.planner.period_s / 2,
        inputs=(
            Input(source="estimator", stream="state", msg_type=StateEstimate, policy=NEWEST),
            Input(source="planner", stream="path", msg_type=PathMsg, policy=NEWEST),
            STATUS,
        ),
        outputs=(
            Output(stream="cmd", msg_type=VelocityCommand),
            Output(stream="ack", msg_type=PathAck),
        ),
    )


def _services(s: Scenario) -> tuple[Service, ...]:
    onboard = commander(s) == "tracker"
    auv = s.sensor.navigation == "dvl_usbl"  # odometry and USBL fixes instead of nav fixes
    return (
        Service(
            name="sensor",
            factory=make_sensor,
            period_s=s.sensor.period_s,
            inputs=(Input(source="vehicle", stream="truth", msg_type=TruthState, policy=NEWEST),),
            outputs=(
                *(
                    (
                        Output(stream="odometry", msg_type=Odometry),
                        Output(stream="fix", msg_type=PositionFix),
                    )
                    if auv
                    else (Output(stream="nav", msg_type=NavFix),)
                ),
                Output(stream="obstacles", msg_type=ObstacleDetections),
            ),
        ),
        Service(
            name="estimator",
            factory=make_estimator,
            period_s=s.estimator.period_s,
            inputs=(
                *(
                    (
                        Input(source="sensor", stream="odometry", msg_type=Odometry),
                        Input(source="sensor", stream="fix", msg_type=PositionFix),
                    )
                    if auv
                    else (Input(source="sensor", stream="nav", msg_type=NavFix),)
                ),
                Input(source="sensor", stream="obstacles", msg_type=ObstacleDetections),
            ),
            outputs=(
                Output(stream="state", msg_type=StateEstimate),
                Output(stream="tracks", msg_type=ObstacleTracks),
            ),
        ),
        Service(
            name="planner",
            factory=make_planner,
            period_s=s.planner.period_s,
            offset_s=s.planner.period_s / 2,  # half a period after the estimator publishes
            inputs=(
                Input(source="estimator", stream="state", msg_type=StateEstimate, policy=NEWEST),
                Input(source="estimator", stream="tracks", msg_type=ObstacleTracks, policy=NEWEST),
                *(
                    (Input(source="tracker", stream="ack", msg_type=PathAck, policy=NEWEST),)
                    if onboard
                    else (STATUS,)
                ),
            ),
            outputs=(
                Output(stream="path", msg_type=PathMsg),
                *(() if onboard else (Output(stream="cmd", msg_type=VelocityCommand),)),
            ),
        ),
        Service(
            name="vehicle",
            factory=make_vehicle,
            period_s=s.vehicle.period_s,
            inputs=(Input(source=commander(s), stream="cmd", msg_type=VelocityCommand),),
            outputs=(
                Output(stream="truth", msg_type=TruthState),
                Output(stream="status", msg_type=VehicleStatus),
            ),
        ),
    )


def _start(s: Scenario) -> tuple[float, float, float]:
    st = s.world.start
    return (st.x_m, st.y_m, st.theta_rad)


def make_sensor(
    ctx: CoreContext, others: Mapping[str, tuple[int, float]] | None = None, phase_s: float = 0.0
) -> SensorCore:
    """The sensor; in a fleet `others` maps the other vehicles' truth sources to (obstacle
    id, hull radius), and `phase_s` is its vehicle's phase (services/mission/fleet.py)."""
    from services.sensor.core import SensorCore

    s = ctx.scenario
    return SensorCore(
        s.sensor,
        World(s.world),
        ctx.rng,
        own=ctx.sibling("vehicle"),
        others=others,
        phase_s=phase_s,
    )


def make_estimator(ctx: CoreContext) -> EstimatorCore:
    """The estimator, its belief started at the world's start pose and speed."""
    from services.estimator.core import EstimatorCore

    s = ctx.scenario
    return EstimatorCore(
        s.estimator,
        _start(s),
        area=s.world.area,
        start_speed_mps=s.world.start.speed_mps,
        sonar=s.sensor,
    )


def make_planner(
    ctx: CoreContext,
    others: Mapping[str, tuple[int, float]] | None = None,
    earlier: frozenset[str] = frozenset(),
    pose_every_s: float = 0.0,
    intent_every_s: float = 0.0,
    ramps: Mapping[str, float] | None = None,
) -> PlannerCore:
    """The planner; in a fleet `others` maps the other vehicles' ids to (obstacle id, hull
    radius), whose broadcast intents it plans around (services/planner/safety/intent.py): all of
    them, or with planner.deconfliction = "priority" those `earlier` in [[vehicles]]; `ramps`
    their speed ramps on a path."""
    from common.runtime.deferred import InThread
    from services.planner.core import PlannerCore
    from services.planner.safety.intent import FleetIntents

    s = ctx.scenario
    # delay compensation starts from the downlink's modelled delay (planner/cmd -> vehicle)
    # until the vehicle reports the delay it measures
    down = profile_for(s.network, link_name("planner", "cmd", "vehicle"))
    return PlannerCore(
        command_loop(s, logging.getLogger("tidelink.planner"), expected_downlink_s=down.delay_s),
        s.planner,
        s.vehicle,
        s.world,
        commands=commander(s) == "planner",
        intents=None
        if others is None
        else FleetIntents(
            others,
            s.planner.intent_max_age_s,
            earlier if s.planner.deconfliction == "priority" else None,
            ramps,
            parked_within_m=s.world.goal_tolerance_m,
            margin_m=s.planner.intent_margin_m,
        ),
        pose_every_s=pose_every_s,
        intent_every_s=intent_every_s,
        # on the wall clock a replan is made beside the steps (common/runtime/deferred.py)
        plans=InThread(name="tidelink-plan") if s.runtime.kind == "realtime" else None,
    )


def make_tracker(ctx: CoreContext) -> TrackerCore:
    """The onboard path follower (controller.placement = "onboard")."""
    from services.tracker.core import TrackerCore

    return TrackerCore(command_loop(ctx.scenario, logging.getLogger("tidelink.tracker")))


def command_loop(
    s: Scenario, log: logging.Logger, *, expected_downlink_s: float = 0.0
) -> CommandLoop[PathArcReference]:
    """The frame a core that commands the vehicle steers in (services/control/loop.py), built
    alike for the planner and the onboard tracker, so that their commands are the same."""
    from services.control.loop import CommandLoop

    return CommandLoop(
        s.planner, s.controller, s.vehicle, s.world, log, expected_downlink_s=expected_downlink_s
    )


def current_field(s: Scenario) -> CurrentField:
    """The run's ocean current: built from the world and the run's seed alone, so every vehicle
    of a fleet (each with its member scenario) moves in the same water."""
    return CurrentField(s.world.current, s.world.area, s.run.seed)


def make_vehicle(
    ctx: CoreContext, hull_scans_s: tuple[tuple[float, float], ...] = ()
) -> VehicleCore:
    """The vehicle; in a fleet `hull_scans_s` are the other vehicles' sonar scans, (period,
    first scan) each (it publishes its hull for them: services/mission/fleet.py)."""
    from services.vehicle.core import VehicleCore

    s = ctx.scenario
    world, r = World(s.world), s.vehicle.radius_m
    return VehicleCore(
        s.vehicle,
        _start(s),
        clearance=lambda x, y, t: world.clearance(x, y, r, t),
        current=current_field(s),
        commander=ctx.sibling(commander(s)),  # defence in depth: whatever the bus lets through
        hull_scans_s=hull_scans_s,
        start_speed_mps=s.world.start.speed_mps,
    )
