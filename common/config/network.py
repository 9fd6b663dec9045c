"""Network-model configuration: per-link profiles, per-link overrides and scheduled outages.

A *link* is one stream as seen by one receiving service, named ``"<source>/<stream>-><receiver>"``
(e.g. ``"sensor/nav->estimator"``). Overrides and outages name links exactly or by one of two
patterns: ``"<source>/<stream>->*"`` (that stream, to every receiver) or ``"*-><receiver>"``
(every stream into that receiver).

In a fleet a service is named "<vehicle>.<service>" (auv2.planner): a name or pattern without
a vehicle id covers that link of every vehicle and between vehicles ("planner/cmd->vehicle"
covers "auv2.planner/cmd->auv2.vehicle"), one with "other." as the sender's id only the links
from another vehicle ("other.planner/path->planner": every vehicle's intent paths), a
qualified one only the links it names; the most specific wins.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Literal

from common.config.checks import nonneg, probability
from common.config.errors import ConfigValueError

JitterKind = Literal["none", "normal", "uniform", "exponential", "pareto"]
LossKind = Literal["none", "bernoulli", "gilbert_elliott"]

_NAME = r"[A-Za-z0-9_.\-]+"  # service / stream names: no '/', '>' or '*'
_LINK_RE = re.compile(rf"^(?P<src>{_NAME})/(?P<stream>{_NAME})->(?P<dst>{_NAME})$")
_SRC_PATTERN_RE = re.compile(rf"^(?P<src>{_NAME})/(?P<stream>{_NAME})->\*$")
_DST_PATTERN_RE = re.compile(rf"^\*->(?P<dst>{_NAME})$")
_SERVICE_RE = re.compile(rf"^{_NAME}$")


def link_name(source_service: str, stream: str, receiver: str) -> str:
    """Canonical link name ``"source/stream->receiver"``; raises ValueError on a bad part."""
    name = f"{source_service}/{stream}->{receiver}"
    if _LINK_RE.match(name) is None:
        raise ConfigValueError(
            "link", f"{name!r} is not a valid link name, expected 'source/stream->receiver'"
        )
    return name


def parse_link(link: str) -> tuple[str, str, str]:
    """Split an exact link name into (source_service, stream, receiver)."""
    m = _LINK_RE.match(link)
    if m is None:
        raise ConfigValueError(
            "link", f"{link!r} is not a valid link name, expected 'source/stream->receiver'"
        )
    return m["src"], m["stream"], m["dst"]


def _check_link_pattern(field: str, pattern: str) -> None:
    if not (
        _LINK_RE.match(pattern) or _SRC_PATTERN_RE.match(pattern) or _DST_PATTERN_RE.match(pattern)
    ):
        raise ConfigValueError(
            field,
            f"{pattern!r} is not a link or link pattern, expected "
            "'source/stream->receiver', 'source/stream->*' or '*->receiver'",
        )


# in a link name, "another vehicle of the fleet" ("other.planner/path->planner")
OTHER = "other"


def _fleetless(name: str) -> str:
    """A service name without its fleet vehicle's id: "auv2.planner" -> "planner"."""
    return name.rpartition(".")[2]


def _forms(link: str) -> tuple[tuple[str, str, str], ...]:
    """(exact, 'src/stream->*', '*->dst') of a link, then (a link between two vehicles) with
    'other.' for the sender's id, then without vehicle ids."""
    src, stream, dst = parse_link(link)
    out = [(link, f"{src}/{stream}->*", f"*->{dst}")]
    bare_src, bare_dst = _fleetless(src), _fleetless(dst)
    if (bare_src, bare_dst) == (src, dst):
        return tuple(out)
    sender, receiver = src.rpartition(".")[0], dst.rpartition(".")[0]
    if sender and receiver and sender != receiver:
        other = f"{OTHER}.{bare_src}"
        out.append((f"{other}/{stream}->{bare_dst}", f"{other}/{stream}->*", f"*->{bare_dst}"))
    out.append((f"{bare_src}/{stream}->{bare_dst}", f"{bare_src}/{stream}->*", f"*->{bare_dst}"))
    return tuple(out)


def link_matches(pattern: str, link: str) -> bool:
    """Whether an exact link name, or a ``src/stream->*`` / ``*->dst`` pattern, covers ``link``
    (in a fleet also without the vehicle ids, see the module docstring)."""
    return any(pattern in forms for forms in _forms(link))


@dataclass(frozen=True, kw_only=True)
class LinkProfile:
    """How one link behaves: delay + jitter (or a trace), loss, duplication, order, bandwidth.

    The defaults describe an ideal link: no delay, no loss, FIFO, unlimited bandwidth.
    """

    # one-way delay = delay_s + jitter (jitter >= 0 except 'uniform', which is centred)
    delay_s: float = 0.0
    # jitter distribution; jitter_s is its scale:
    #   normal: std of N(0, jitter_s^2), the total delay truncated (conditioned) to >= 0;
    #   uniform: half-width, jitter ~ U(-jitter_s, +jitter_s) (needs jitter_s <= delay_s);
    #   exponential: mean of Exp(1/jitter_s);
    #   pareto: scale of a Lomax (Pareto II) jitter jitter_s*((1-u)^(-1/shape) - 1) >= 0,
    #           mean jitter_s/(shape-1), finite variance needs pareto_shape > 2
    jitter: JitterKind = "none"
    jitter_s: float = 0.0
    pareto_shape: float = 3.0
    # text/CSV file of one-way delays (s), replayed cyclically by seq; "" = none.
    # With a trace the delay is delay_s + trace[seq % len(trace)] and jitter must be 'none'.
    trace_file: str = ""
    # loss model: bernoulli uses loss_p; gilbert_elliott uses the ge_* fields
    loss: LossKind = "none"
    loss_p: float = 0.0
    ge_p_gb: float = 0.01  # P(good -> bad) per message
    ge_p_bg: float = 0.3  # P(bad -> good) per message
    ge_loss_good: float = 0.0  # loss probability in the good state
    ge_loss_bad: float = 1.0  # loss probability in the bad state
    # probability that a delivered message arrives twice (the copy has its own delay draw)
    duplicate_p: float = 0.0
    # True: a message never overtakes an earlier one on this link (TCP-like, Zenoh default)
    fifo: bool = True
    # serialisation bandwidth (bit/s) of the link; 0 = unlimited (no queue)
    bandwidth_bps: float = 0.0
    # messages that may wait behind the one being transmitted; more are tail-dropped
    queue_len: int = 64

    def __post_init__(self) -> None:
        nonneg("delay_s", self.delay_s)
        nonneg("jitter_s", self.jitter_s)
        if self.jitter not in ("none", "normal", "uniform", "exponential", "pareto"):
            raise ConfigValueError(
                "jitter",
                f"{self.jitter!r} is unknown, expected one of "
                "'none', 'normal', 'uniform', 'exponential', 'pareto'",
            )
        if self.jitter == "none" and self.jitter_s != 0.0:
            raise ConfigValueError(
                "jitter_s", f"{self.jitter_s!r} given but jitter is 'none', expected 0"
            )
        if self.jitter == "uniform" and self.jitter_s > self.delay_s:
            raise ConfigValueError(
                "jitter_s",
                f"uniform half-width {self.jitter_s!r} exceeds delay_s {self.delay_s!r}, "
                "expected jitter_s <= delay_s so the delay stays >= 0",
            )
        if not (math.isfinite(self.pareto_shape) and self.pareto_shape > 2.0):
            raise ConfigValueError(
                "pareto_shape", f"{self.pareto_shape!r} is invalid, expected > 2 (finite variance)"
            )
        if self.trace_file and self.jitter != "none":
            raise ConfigValueError(
                "jitter",
                f"{self.jitter!r} given with trace_file {self.trace_file!r}, "
                "expected 'none' (a trace replaces the jitter)",
            )
        if self.loss not in ("none", "bernoulli", "gilbert_elliott"):
            raise ConfigValueError(
                "loss",
                f"{self.loss!r} is unknown, expected 'none', 'bernoulli' or 'gilbert_elliott'",
            )
        probability("loss_p", self.loss_p)
        if self.loss != "bernoulli" and self.loss_p != 0.0:
            raise ConfigValueError(
                "loss_p", f"{self.loss_p!r} given but loss is {self.loss!r}, expected 0"
            )
        for name in ("ge_p_gb", "ge_p_bg", "ge_loss_good", "ge_loss_bad", "duplicate_p"):
            probability(name, getattr(self, name))
        if self.loss == "gilbert_elliott" and self.ge_p_gb + self.ge_p_bg <= 0.0:
            raise ConfigValueError(
                "ge_p_bg",
                "ge_p_gb + ge_p_bg is 0, expected > 0 (the chain needs a stationary state)",
            )
        nonneg("bandwidth_bps", self.bandwidth_bps)
        if self.queue_len < 1:
            raise ConfigValueError(
                "queue_len", f"{self.queue_len!r} is invalid, expected an integer >= 1"
            )


@dataclass(frozen=True, kw_only=True)
class Outage:
    """A window [start_s, end_s) in which a link, or every link touching a service, is down.

    Exactly one of ``link`` (a link name or pattern) and ``service`` (sender or receiver) is set.
    """

    start_s: float
    end_s: float  # may be inf: a permanent partition
    link: str = ""
    service: str = ""

    def __post_init__(self) -> None:
        nonneg("start_s", self.start_s)
        if math.isnan(self.end_s) or self.end_s <= self.start_s:
            raise ConfigValueError(
                "end_s", f"{self.end_s!r} is invalid, expected end_s > start_s ({self.start_s!r})"
            )
        if bool(self.link) == bool(self.service):
            raise ConfigValueError(
                "link", "exactly one of link and service must be set for an outage"
            )
        if self.link:
            _check_link_pattern("link", self.link)
        elif _SERVICE_RE.match(self.service) is None:
            raise ConfigValueError("service", f"{self.service!r} is not a valid service name")

    def applies_to(self, link: str) -> bool:
        """Whether this outage takes ``link`` down (by name/pattern, or as sender or receiver)."""
        if self.link:
            return link_matches(self.link, link)
        src, _, dst = parse_link(link)
        return self.service in (src, dst, _fleetless(src), _fleetless(dst))


@dataclass(frozen=True, kw_only=True)
class LinkOverride:
    """A complete profile for the links a name or pattern covers (it does not merge fields)."""

    link: str  # "src/stream->dst", "src/stream->*" or "*->dst"
    profile: LinkProfile

    def __post_init__(self) -> None:
        _check_link_pattern("link", self.link)


@dataclass(frozen=True, kw_only=True)
class NetworkConfig:
    """The modelled network: a default profile, per-link overrides and scheduled outages."""

    default: LinkProfile = LinkProfile()
    links: tuple[LinkOverride, ...] = ()
    outages: tuple[Outage, ...] = ()

    def __post_init__(self) -> None:
        seen: set[str] = set()
        for o in self.links:
            if o.link in seen:
                raise ConfigValueError(
                    "links", f"{o.link!r} is overridden twice, expected each once"
                )
            seen.add(o.link)


def profile_for(cfg: NetworkConfig, link: str) -> LinkProfile:
    """Resolve a link's profile: exact name, then 'src/stream->*', then '*->dst', then (in a
    fleet) the same without vehicle ids, then default."""
    by_name = {o.link: o.profile for o in cfg.links}
    for forms in _forms(link):
        for key in forms:
            if key in by_name:
                return by_name[key]
    return cfg.default
