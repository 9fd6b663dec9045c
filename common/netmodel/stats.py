"""Per-link counters and delay percentiles, accumulated in O(1) per message."""

from __future__ import annotations

import math
from bisect import bisect_left
from dataclasses import dataclass
from itertools import accumulate

from common.messages import LINK_COUNTS

# Delay histogram: bin 0 holds delays below 1 us, bin i >= 1 holds [D0*R^(i-1), D0*R^i), so a
# percentile is reported within a factor sqrt(R) (0.5 %) of the exact sample value.
_D0_S = 1e-6
_RATIO = 1.01
_LOG_RATIO = math.log(_RATIO)
_N_BINS = 1 + math.ceil(math.log(1e4 / _D0_S) / _LOG_RATIO)  # up to 10^4 s; larger go in the last


# the accumulator's counters, which a snapshot copies under the same names
_COUNTS = (*LINK_COUNTS, "loss_bursts", "max_loss_burst", "bytes_sent")


@dataclass(frozen=True, kw_only=True)
class LinkStatsSnapshot:
    """Plain-number statistics of one link (sent = delivered + all drops)."""

    sent: int
    delivered: int  # messages with at least one copy delivered
    dropped_loss: int
    dropped_outage: int
    dropped_queue: int
    duplicated: int  # messages delivered twice
    delay_p50_s: float  # of the first copy; 0.0 until something is delivered
    delay_p95_s: float
    delay_p99_s: float
    delay_mean_s: float  # exact mean
    delay_max_s: float  # exact maximum
    loss_bursts: int  # maximal runs of consecutive messages dropped by loss
    max_loss_burst: int
    bytes_sent: int = 0  # encoded size of every message offered to the link


class LinkStatsAccumulator:
    """Accumulates one link's decisions; ``snapshot()`` reads them as plain numbers."""

    def __init__(self) -> None:
        self.sent = 0
        self.delivered = 0
        self.dropped_loss = 0
        self.dropped_outage = 0
        self.dropped_queue = 0
        self.duplicated = 0
        self.bytes_sent = 0
        self.loss_bursts = 0
        self.max_loss_burst = 0
        self._run = 0  # length of the current run of loss drops
        self.delays = DurationHistogram()  # of the first copy of each delivered message

    def record(
        self,
        send_time: float,
        delivered_at: tuple[float, ...],
        cause: str | None,
        size_bytes: int = 0,
    ) -> None:
        """Count one decided message (its delivery times, or its drop cause, and its size)."""
        self.sent += 1
        self.bytes_sent += size_bytes
        if cause == "loss":
            self.dropped_loss += 1
            self._run += 1
            if self._run == 1:
                self.loss_bursts += 1
            if self._run > self.max_loss_burst:
                self.max_loss_burst = self._run
            return
        self._run = 0
        if cause is not None:
            if cause == "outage":
                self.dropped_outage += 1
            elif cause == "queue":
                self.dropped_queue += 1
        if not delivered_at:
            return
        self.delivered += 1
        if len(delivered_at) == 1:  # nearly always: no min() over one copy
            d = delivered_at[0] - send_time
        else:
            self.duplicated += 1
            d = min(delivered_at) - send_time
        # >= 0 up to the us rounding of delivery times (exact when send_time is on the us
        # grid); max(0.0, d) without the call
        self.delays.record(d if d > 0.0 else 0.0)

    def percentile(self, q: float) -> float:
        """Nearest-rank q-quantile (0 < q <= 1) of the first-copy delay, to 0.5 %; 0 if empty."""
        return self.delays.quantiles(q)[0]

    def quantiles(self, *qs: float) -> tuple[float, ...]:
        """percentile(q) for each q (DurationHistogram.quantiles)."""
        return self.delays.quantiles(*qs)

    def snapshot(self) -> LinkStatsSnapshot:
        """The counters and delay statistics so far."""
        p50, p95, p99 = self.delays.quantiles(0.5, 0.95, 0.99)
        counts = {name: getattr(self, name) for name in _COUNTS}
        return LinkStatsSnapshot(
            **counts,
            delay_p50_s=p50,
            delay_p95_s=p95,
            delay_p99_s=p99,
            delay_mean_s=self.delays.mean,
            delay_max_s=self.delays.max,
        )


class DurationHistogram:
    """Durations (s) in logarithmic bins: count, exact mean and maximum, and nearest-rank
    quantiles to 0.5 %, each recorded in O(1) (a link's delays, a loop's step times)."""

    def __init__(self) -> None:
        self.count = 0
        self._sum = 0.0
        self.max = 0.0
        # Only the non-empty bins are kept: a link's delays fill a few of the ~2300 bins, and
        # a host reads the percentiles of every outgoing link each second (a fleet of 16: ~30
        # links a host; a pass over every bin was the fleet's largest per-vehicle cost growing
        # with N). They are kept in order as they appear (rarely, once a link's delays have
        # spread), so a snapshot's quantiles sort nothing (~200 bins of a jittered link, sorted
        # and summed in Python, were most of a host's statistics each second), and their
        # counts beside them in the same order, so a snapshot sums that list as it is (a count
        # looked up by bin in a dict, bin after bin, took twice as long; a record finds its
        # bin by bisection as fast as in the dict).
        self._filled: list[int] = []
        self._counts: list[int] = []  # _counts[i]: durations in bin _filled[i]

    def record(self, d: float) -> None:
        """Count one duration d >= 0 (s)."""
        self.count += 1
        self._sum += d
        if d > self.max:
            self.max = d
        # the bin (module head), computed here rather than by a function: every message of
        # a link, and every delivery to a host, records one
        if d < _D0_S:
            b = 0
        else:
            b = 1 + int(math.log(d / _D0_S) / _LOG_RATIO)
            if b >= _N_BINS:  # the last bin holds every larger duration
                b = _N_BINS - 1
        filled = self._filled
        i = bisect_left(filled, b)
        if i < len(filled) and filled[i] == b:
            self._counts[i] += 1
        else:
            filled.insert(i, b)
            self._counts.insert(i, 1)

    @property
    def mean(self) -> float:
        """The exact mean; 0 if empty."""
        return self._sum / self.count if self.count else 0.0

    def quantiles(self, *qs: float) -> tuple[float, ...]:
        """The nearest-rank q-quantile (0 < q <= 1) for each q, from one cumulative pass over
        the non-empty bins (a snapshot asks three, a host snapshots its links every second);
        0 if empty."""
        if self.count == 0:
            return tuple(0.0 for _ in qs)
        filled = self._filled
        cumulative = list(accumulate(self._counts))
        out = []
        for q in qs:
            rank = max(1, math.ceil(q * self.count))
            j = bisect_left(cumulative, rank)  # the first bin whose count reaches the rank
            if j >= len(cumulative):  # unreachable: the bins hold every recorded duration
                out.append(self.max)
                continue
            i = filled[j]
            if i == 0:
                out.append(0.0)
            else:
                mid = _D0_S * _RATIO ** (i - 0.5)  # geometric centre of the bin
                out.append(min(mid, self.max))
        return tuple(out)
