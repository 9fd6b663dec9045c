"""One acoustic link: modem queue, frame errors from the link budget, propagation at sound speed.

Pipeline for message ``seq`` of ``size_bytes`` sent at ``t`` with the nodes ``range_m`` apart:
1. outage: the link is down at ``t`` -> dropped ("outage");
2. the sender's modem takes the frame when the channel is free (half duplex, FIFO) or drops
   it when its queue is full ("queue");
3. frame error ("loss"): a draw ``U_FRAME_ERROR`` of (seed, link, seq) below the frame error
   rate at this range and size (common/netmodel/acoustic.py);
4. delivered at start + modem latency + frame duration + range / sound speed, unless an
   outage cuts the flight ("outage"). Rounded to whole microseconds like every link.
"""

from __future__ import annotations

from collections.abc import Iterable

from common.config.acoustic import AcousticMedium
from common.config.network import Outage, parse_link
from common.netmodel.acoustic import band_noise_db, frame_error_rate
from common.netmodel.link import Decision, check_send, us
from common.netmodel.modem import Modem
from common.netmodel.outage import OutageSchedule
from common.netmodel.rng import U_FRAME_ERROR, CounterRng, unit
from common.netmodel.stats import LinkStatsAccumulator


class AcousticLink:
    """The stateful model of one acoustic link; deterministic in (seed, link, seq, send time,
    size, range) and the sending modem's queue. Call ``decide`` in send order."""

    def __init__(
        self,
        medium: AcousticMedium,
        *,
        seed: int,
        link: str,
        modem: Modem,
        outages: Iterable[Outage] = (),
    ) -> None:
        _src, self._stream, _dst = parse_link(link)
        self.medium = medium
        self.link = link
        self.stats = LinkStatsAccumulator()
        self._rng = CounterRng(seed=seed, link=link)
        self._modem = modem
        self._outages = OutageSchedule(link, outages)
        self._noise_db = band_noise_db(medium)  # fixed per medium: computed once
        self._last_seq = -1
        self._last_send = float("-inf")

    def decide(self, seq: int, send_time: float, size_bytes: int, range_m: float) -> Decision:
        """Decide the delivery of message ``seq`` sent at ``send_time`` over ``range_m``."""
        check_send(seq, send_time, size_bytes, self._last_seq, self._last_send)
        self._last_seq, self._last_send = seq, send_time
        decision = self._decide(seq, send_time, size_bytes, range_m)
        self.stats.record(send_time, decision.delivered_at, decision.drop_cause, size_bytes)
        return decision

    def _decide(self, seq: int, t: float, size_bytes: int, range_m: float) -> Decision:
        if self._outages.down_at(t):
            return Decision(seq=seq, delivered_at=(), drop_cause="outage")
        start = self._modem.offer((self._stream, seq), t, size_bytes)
        if start is None:
            return Decision(seq=seq, delivered_at=(), drop_cause="queue")
        m = self.medium
        fer = frame_error_rate(m, range_m, size_bytes, self._noise_db)
        if unit(self._rng.words(seq)[U_FRAME_ERROR]) < fer:
            return Decision(seq=seq, delivered_at=(), drop_cause="loss")
        arrival = us(
            start + m.modem_latency_s + m.frame_s(size_bytes) + range_m / m.sound_speed_mps
        )
        if self._outages.cuts(t, arrival):
            return Decision(seq=seq, delivered_at=(), drop_cause="outage")
        return Decision(seq=seq, delivered_at=(arrival,))
