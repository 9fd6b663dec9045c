"""One-way delay of a link: a constant plus jitter by inverse CDF of one uniform, or a trace.

Every distribution is sampled by inverting its CDF at a single counter-based uniform u in [0, 1),
so a draw costs a few float operations and never loops (no rejection sampling).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from statistics import NormalDist

from common.config.network import LinkProfile

_STD_NORMAL = NormalDist()
_ONE_MINUS_EPS = 1.0 - 2.0**-53
_TINY = 2.0**-1000


def _clip0(delay: float) -> float:
    return delay if delay > 0.0 else 0.0


class DelaySampler:
    """Maps (u, seq, copy) to a one-way delay in seconds (>= 0) for one link profile."""

    def __init__(self, profile: LinkProfile, trace: Sequence[float] | None = None) -> None:
        self._base = profile.delay_s
        self._scale = profile.jitter_s
        self._trace: tuple[float, ...] = ()
        # sample(u, seq, copy): the delay (s) for uniform u; trace replay indexes by seq + copy
        # instead. The draw function of the profile's kind, chosen once: no kind is compared
        # per message, and no method stands between a link and it (one call a message fewer)
        self.sample: Callable[[float, int, int], float]
        if profile.trace_file or trace is not None:
            self._trace = tuple(trace) if trace is not None else load_trace(profile.trace_file)
            if not self._trace:
                raise ValueError("trace_file: the trace holds no delays, expected at least one")
            self.sample = self._from_trace
        elif profile.jitter == "none" or profile.jitter_s == 0.0:
            self.sample = self._constant
        elif profile.jitter == "normal":
            # truncation of delay_s + N(0, s^2) to [0, inf): sample u within [Phi(a), 1)
            # where a = -delay_s / s is the standardised truncation point
            self._lo = _STD_NORMAL.cdf(-profile.delay_s / profile.jitter_s)
            self.sample = self._normal
        elif profile.jitter == "uniform":
            self.sample = self._uniform
        elif profile.jitter == "exponential":
            self.sample = self._exponential
        else:  # pareto
            self._neg_inv_shape = -1.0 / profile.pareto_shape
            self.sample = self._pareto

    def _constant(self, u: float, seq: int, copy: int) -> float:
        return self._base

    def _from_trace(self, u: float, seq: int, copy: int) -> float:
        # cyclic replay by seq; a duplicate copy takes the next trace entry
        return self._base + self._trace[(seq + copy) % len(self._trace)]

    def _normal(self, u: float, seq: int, copy: int) -> float:
        p = self._lo + u * (1.0 - self._lo)
        # inv_cdf needs p strictly in (0, 1): min(max(p, 2**-1000), 1 - eps) without the calls
        if _TINY > p:
            p = _TINY
        if _ONE_MINUS_EPS < p:
            p = _ONE_MINUS_EPS
        return _clip0(self._base + self._scale * _STD_NORMAL.inv_cdf(p))

    def _uniform(self, u: float, seq: int, copy: int) -> float:
        return _clip0(self._base + self._scale * (2.0 * u - 1.0))

    def _exponential(self, u: float, seq: int, copy: int) -> float:
        return self._base - self._scale * math.log1p(-u)

    def _pareto(self, u: float, seq: int, copy: int) -> float:
        # Lomax: x = s * ((1-u)^(-1/shape) - 1) = s * expm1(-log1p(-u) / shape)
        return self._base + self._scale * math.expm1(math.log1p(-u) * self._neg_inv_shape)


def parse_trace(text: str, source: str = "<trace>") -> tuple[float, ...]:
    """Parse delays (s) from text: one per line, or CSV rows whose last field is the delay.

    Blank lines and lines starting with '#' are skipped; a non-numeric first row is a header.
    """
    delays: list[float] = []
    first = True
    for lineno, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        field = stripped.split(",")[-1].strip()
        try:
            value = float(field)
        except ValueError:
            if first:  # header row, e.g. "seq,delay_s"
                first = False
                continue
            raise ValueError(
                f"trace_file: {source}:{lineno}: {field!r} is not a number, expected a delay in s"
            ) from None
        first = False
        if not (math.isfinite(value) and value >= 0.0):
            raise ValueError(
                f"trace_file: {source}:{lineno}: delay {value!r} is invalid, expected finite >= 0"
            )
        delays.append(value)
    if not delays:
        raise ValueError(f"trace_file: {source} holds no delays, expected at least one")
    return tuple(delays)


def load_trace(path: str) -> tuple[float, ...]:
    """Read and parse a delay trace file (see ``parse_trace``)."""
    return parse_trace(Path(path).read_text(encoding="utf-8"), source=path)
