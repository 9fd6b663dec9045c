"""All links of a run: one LinkModel per link, built on first use from the network config."""

from __future__ import annotations

from common.config.network import NetworkConfig, link_name, profile_for
from common.netmodel.link import Decision, LinkModel
from common.netmodel.stats import LinkStatsSnapshot


class NetworkModel:
    """Lazily creates and keeps the LinkModel of each link a runtime sends on."""

    def __init__(self, cfg: NetworkConfig, *, seed: int) -> None:
        self.cfg = cfg
        self.seed = seed
        self._links: dict[str, LinkModel] = {}

    def link(self, source_service: str, stream: str, receiver: str) -> LinkModel:
        """The model of ``source/stream->receiver`` (created with its resolved profile)."""
        name = link_name(source_service, stream, receiver)
        model = self._links.get(name)
        if model is None:
            model = LinkModel(
                profile_for(self.cfg, name), seed=self.seed, link=name, outages=self.cfg.outages
            )
            self._links[name] = model
        return model

    def decide(
        self, source_service: str, stream: str, receiver: str, seq: int, send_time: float, size: int
    ) -> Decision:
        """Shorthand for ``link(...).decide(seq, send_time, size)``."""
        return self.link(source_service, stream, receiver).decide(seq, send_time, size)

    def snapshots(self) -> dict[str, LinkStatsSnapshot]:
        """Statistics of every link used so far, by link name (sorted)."""
        return {name: self._links[name].stats.snapshot() for name in sorted(self._links)}
