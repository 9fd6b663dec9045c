"""All links of a run: one link model per link, built on first use from network and placement."""

from __future__ import annotations

import math

from common.config.network import LinkProfile, NetworkConfig, link_name, profile_for
from common.config.placement import VEHICLE_NODE, PlacementConfig
from common.netmodel.acoustic_link import AcousticLink
from common.netmodel.link import Decision, LinkModel
from common.netmodel.modem import Modem
from common.netmodel.stats import LinkStatsSnapshot

_LOCAL = LinkProfile()  # two services on one node: ideal, no modelled fault


class NetworkModel:
    """Lazily creates and keeps the model of each link a runtime sends on.

    A link's model follows the placement (common/config/placement.py): local links are
    ideal, generic ones use their ``[network]`` profile and outages, acoustic ones the
    acoustic medium with the range between the two nodes at the send time. The vehicle
    node's position is the newest the sender knows (``observe_vehicle``), starting from
    the vehicle's start: a pure function of what the sending host has seen, so lockstep and
    inproc decide alike.
    """

    def __init__(
        self,
        cfg: NetworkConfig,
        *,
        seed: int,
        placement: PlacementConfig | None = None,
        vehicle_start: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        self.cfg = cfg
        self.seed = seed
        self.placement = placement or PlacementConfig()
        self.vehicle_xy = vehicle_start
        self._links: dict[str, LinkModel | AcousticLink] = {}
        # by (source, stream, receiver): a model is looked up for every message it decides
        self._by_ends: dict[tuple[str, str, str], LinkModel | AcousticLink] = {}
        self._modems: dict[tuple[str, str], Modem] = {}

    def observe_vehicle(self, x: float, y: float) -> None:
        """The vehicle's newest true position known to this sender (for acoustic ranges)."""
        self.vehicle_xy = (x, y)

    def link(self, source_service: str, stream: str, receiver: str) -> LinkModel | AcousticLink:
        """The model of ``source/stream->receiver`` (created on first use)."""
        ends = (source_service, stream, receiver)
        model = self._by_ends.get(ends)
        if model is None:
            name = link_name(source_service, stream, receiver)
            model = self._links.get(name)
            if model is None:
                model = self._links[name] = self._build(name, source_service, receiver)
            self._by_ends[ends] = model
        return model

    def _build(self, name: str, source: str, receiver: str) -> LinkModel | AcousticLink:
        p = self.placement
        medium = p.link_medium(source, receiver)
        if medium == "local":
            return LinkModel(_LOCAL, seed=self.seed, link=name)
        if medium == "generic":
            return LinkModel(
                profile_for(self.cfg, name), seed=self.seed, link=name, outages=self.cfg.outages
            )
        # one modem per sending node and node pair: a message to several services on the
        # other node is one broadcast frame
        nodes = (p.node_of(source), p.node_of(receiver))
        modem = self._modems.get(nodes)
        if modem is None:
            modem = self._modems[nodes] = Modem(p.acoustic)
        return AcousticLink(
            p.acoustic, seed=self.seed, link=name, modem=modem, outages=self.cfg.outages
        )

    def range_m(self, source_service: str, receiver: str) -> float:
        """The distance between the two services' nodes now (m)."""
        p = self.placement
        a, b = p.node_of(source_service), p.node_of(receiver)
        xa, ya = self._position(a)
        xb, yb = self._position(b)
        return math.hypot(xa - xb, ya - yb)

    def _position(self, node: str) -> tuple[float, float]:
        if node == VEHICLE_NODE:
            return self.vehicle_xy
        s = self.placement.station(node)
        return (s.x_m, s.y_m)

    def decide(
        self, source_service: str, stream: str, receiver: str, seq: int, send_time: float, size: int
    ) -> Decision:
        """The delivery of message ``seq`` of ``source/stream`` to ``receiver``."""
        model = self._by_ends.get((source_service, stream, receiver))  # link(), without a call
        if model is None:
            model = self.link(source_service, stream, receiver)
        if isinstance(model, AcousticLink):
            return model.decide(seq, send_time, size, self.range_m(source_service, receiver))
        return model.decide(seq, send_time, size)

    def snapshots(self) -> dict[str, LinkStatsSnapshot]:
        """Statistics of every link used so far, by link name (sorted)."""
        return {name: self._links[name].stats.snapshot() for name in sorted(self._links)}
