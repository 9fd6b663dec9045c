"""The AUV dataflow under a placement: services checked, range taps where acoustic links start."""

from __future__ import annotations

import dataclasses

from common.config.errors import ConfigError
from common.config.network import NetworkConfig, link_matches
from common.config.placement import PlacementConfig
from common.messages import TruthState
from common.runtime.model.core import QueuePolicy
from common.runtime.model.dataflow import Dataflow, Input

# the vehicle's true position, which an acoustic link's range is taken from
TRUTH = ("vehicle", "truth")


def placed(
    flow: Dataflow, placement: PlacementConfig, network: NetworkConfig | None = None
) -> Dataflow:
    """`flow` with a placement applied: a service the placement names must exist (ConfigError
    at placement.services.<name>); every service that sends over an acoustic medium and does
    not already read the vehicle's truth gets a range tap on it (an ideal link the core never
    sees: the host's link model needs where the vehicle is, the sender's known state). A
    `network.links` profile naming a link that is local or acoustic would have no effect:
    ConfigError at network.links[i].link (patterns are broad defaults and pass)."""
    network = network or NetworkConfig()
    for name in placement.services:
        if name not in flow.services:
            raise ConfigError(
                "",
                ("placement", "services", name),
                f"{name!r} is not a service of this mission, expected one of "
                f"{', '.join(map(repr, flow.names))}",
            )
    for i, o in enumerate(network.links):
        if "*" in o.link:
            continue  # a pattern is a broad default (configs/default.toml has 'vehicle/truth->*')
        covered = [lk for lk in flow.links if link_matches(o.link, lk.name)]
        if covered and all(
            placement.link_medium(lk.source, lk.receiver) != "generic" for lk in covered
        ):
            medium = placement.link_medium(covered[0].source, covered[0].receiver)
            raise ConfigError(
                "",
                ("network", "links", i, "link"),
                f"{o.link!r} runs over the {medium} medium of [placement] "
                f"({covered[0].name}), where a network profile has no effect: set "
                "placement.acoustic, or place the services so that the link is generic",
            )
    senders = {
        link.source
        for link in flow.links
        if placement.link_medium(link.source, link.receiver) == "acoustic"
    }
    if not senders - {TRUTH[0]}:
        return flow
    services = []
    for svc in flow.services.values():
        reads_truth = any((i.source, i.stream) == TRUTH for i in svc.inputs)
        if svc.name in senders and svc.name != TRUTH[0] and not reads_truth:
            tap = Input(
                source=TRUTH[0],
                stream=TRUTH[1],
                msg_type=TruthState,
                policy=QueuePolicy.NEWEST,
                tap=True,
            )
            svc = dataclasses.replace(svc, inputs=(*svc.inputs, tap))
        services.append(svc)
    return Dataflow.declare(*services)
