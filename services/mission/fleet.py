"""A fleet's dataflow: the AUV dataflow once per vehicle, plus the links between vehicles.

Each vehicle's services are the single-vehicle ones named "<id>.<service>" (auv2.sensor,
auv2.estimator, auv2.planner, auv2.vehicle), built from that vehicle's scenario (its start,
goal and section overrides: Scenario.member). Between vehicles:

    <other>.vehicle   --hull---> <id>.sensor   the sonar sees the other hulls (simulation: a
                                             sensor samples what is physically there; "hull"
                                             is the other's truth at the steps right before
                                             a scan: services/vehicle/core.py)
    <other>.planner   --pose---> <id>.planner  the other's intent: the estimate its planner plans
    <other>.planner   --intent-> <id>.planner  from (every POSE_PERIOD_S while it is alive) and
                                               the path it follows (each new one at once, then
                                               every INTENT_PERIOD_S: a path is made once per
                                               replan, and one lost would leave the others
                                               without it until the next; intent.py)

so every vehicle is a moving obstacle to the others: with a known trajectory while its intent
arrives (deconfliction by intent; who gives way: planner.deconfliction), else as the track its
sonar contact gives (eq. (12)-(13)).
The intent links are modelled links like any other: "other.planner/pose->planner" and
"other.planner/intent->planner" name them for every vehicle in network profiles.
"""

from __future__ import annotations

import dataclasses
from functools import partial

from common.config.scenario import Scenario
from common.messages import Message, PathMsg, StateEstimate, TruthState
from common.runtime.model.core import QueuePolicy, ServiceCore
from common.runtime.model.dataflow import (
    CoreContext,
    CoreFactory,
    Dataflow,
    Input,
    Output,
    Service,
    qualified,
)
from common.world import World
from services.mission.dataflow import auv_dataflow, make_planner, make_sensor, make_vehicle

# what a planner hears of each other vehicle: its intent (services/planner/safety/intent.py)
INTENT: tuple[tuple[str, str, type[Message]], ...] = (
    ("planner", "pose", StateEstimate),
    ("planner", "intent", PathMsg),
)
POSE_PERIOD_S = 0.5  # a planner's intent pose: 2 Hz, a quarter of the state's rate
INTENT_PERIOD_S = 1.0  # its path in force, again: half planner.intent_max_age_s by default


def fleet_obstacle_ids(s: Scenario) -> dict[str, int]:
    """The obstacle id each vehicle has in the others' sonar scans: after every world id."""
    first = max(World(s.world).obstacle_ids, default=-1) + 1
    return {v.id: first + i for i, v in enumerate(s.vehicles)}


def fleet_dataflow(s: Scenario) -> Dataflow:
    """Every vehicle's AUV dataflow, qualified by its id and shifted by its phase, each
    sensor reading the others' hulls and each planner their intents."""
    ids = fleet_obstacle_ids(s)
    radius = {v.id: v.vehicle.radius_m for v in s.vehicles}
    flows = {vid: auv_dataflow(member) for vid, member in s.members}
    # when each vehicle's sonar scans (period, first scan): the others send their hull just
    # before; its sensor steps at its own offset shifted by the vehicle's phase, and scans
    # every scan_every steps from there
    phase = {v.id: v.phase_s for v in s.vehicles}
    scans = {
        vid: (
            m.sensor.scan_every * m.sensor.period_s,
            (flows[vid].services["sensor"].offset_s + phase[vid]) % m.sensor.period_s,
        )
        for vid, m in s.members
    }
    # how fast each vehicle's speed rises on a new path: its intent, to the others
    ramps = {vid: member.controller.speed.accel_mps2 for vid, member in s.members}
    services: list[Service] = []
    for k, (vid, member) in enumerate(s.members):
        earlier = frozenset(v.id for v in s.vehicles[:k])  # who it gives way to, by priority
        others = {o: (ids[o], radius[o]) for o in ids if o != vid}
        hulls = {qualified(o, "vehicle"): seen for o, seen in others.items()}
        for svc in flows[vid].services.values():
            factory: CoreFactory = svc.factory
            outputs = svc.outputs
            inputs = tuple(
                dataclasses.replace(i, source=qualified(vid, i.source)) for i in svc.inputs
            )
            if svc.name == "sensor":
                factory = partial(make_sensor, others=hulls, phase_s=scans[vid][1])
                inputs += tuple(_newest(src, "hull", TruthState) for src in hulls)
            elif svc.name == "vehicle":
                factory = partial(
                    make_vehicle, hull_scans_s=tuple(scans[o] for o in sorted(others))
                )
                outputs = (*outputs, Output(stream="hull", msg_type=TruthState))
            elif svc.name == "planner":
                factory = partial(
                    make_planner,
                    others=others,
                    earlier=earlier,
                    ramps={o: ramps[o] for o in others},
                    pose_every_s=POSE_PERIOD_S,
                    intent_every_s=INTENT_PERIOD_S,
                )
                outputs = (
                    *outputs,
                    Output(stream="pose", msg_type=StateEstimate),
                    Output(stream="intent", msg_type=PathMsg),
                )
                inputs += tuple(
                    _newest(qualified(o, source), stream, msg_type)
                    for o in others
                    for source, stream, msg_type in INTENT
                )
            if svc.period_s is not None and phase[vid]:
                svc = dataclasses.replace(svc, offset_s=(svc.offset_s + phase[vid]) % svc.period_s)
            services.append(
                dataclasses.replace(
                    svc,
                    name=qualified(vid, svc.name),
                    factory=partial(_as_member, factory, member),
                    inputs=inputs,
                    outputs=outputs,
                )
            )
    return Dataflow.declare(*services)


def _newest(source: str, stream: str, msg_type: type[Message]) -> Input:
    return Input(source=source, stream=stream, msg_type=msg_type, policy=QueuePolicy.NEWEST)


def _as_member(factory: CoreFactory, member: Scenario, ctx: CoreContext) -> ServiceCore:
    """Build a vehicle's core from that vehicle's scenario (the runtime hands the fleet's)."""
    return factory(dataclasses.replace(ctx, scenario=member))
