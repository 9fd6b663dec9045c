"""The pure, seeded network link model shared by every runtime (delay, loss, bandwidth, outages)."""

from common.config.network import link_name, parse_link
from common.netmodel.delay import DelaySampler, load_trace, parse_trace
from common.netmodel.link import Decision, DropCause, LinkModel
from common.netmodel.network import NetworkModel
from common.netmodel.rng import CounterRng
from common.netmodel.stats import LinkStatsAccumulator, LinkStatsSnapshot

__all__ = [
    "CounterRng",
    "Decision",
    "DelaySampler",
    "DropCause",
    "LinkModel",
    "LinkStatsAccumulator",
    "LinkStatsSnapshot",
    "NetworkModel",
    "link_name",
    "load_trace",
    "parse_link",
    "parse_trace",
]
