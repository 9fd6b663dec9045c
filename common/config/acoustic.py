"""The acoustic medium: sound speed, the modem (rate, band, level, latency, queue), ocean noise."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from common.config.checks import int_range, nonneg, probability
from common.config.errors import ConfigValueError

Modulation = Literal["bpsk", "fsk"]


def _within(name: str, x: float, lo: float, hi: float, unit: str) -> None:
    if not (math.isfinite(x) and lo <= x <= hi):
        raise ConfigValueError(name, f"{x!r} is out of range, expected {lo:g} to {hi:g} {unit}")


@dataclass(frozen=True, kw_only=True)
class AcousticMedium:
    """An underwater acoustic link between two modems (docs/acoustic.md has the equations).

    The defaults describe a small commercial modem: 1 kbit/s BPSK on a 5 kHz band around
    10 kHz, 170 dB re 1 uPa at 1 m, moderate shipping, no wind.
    """

    sound_speed_mps: float = 1500.0  # range / sound speed = propagation delay
    bit_rate_bps: float = 1000.0
    frequency_khz: float = 10.0  # carrier (the band's centre)
    bandwidth_khz: float = 5.0
    source_level_db: float = 170.0  # dB re 1 uPa at 1 m
    spreading_k: float = 1.5  # 1 cylindrical, 2 spherical, 1.5 "practical"
    modulation: Modulation = "bpsk"  # coherent BPSK or non-coherent binary FSK
    modem_latency_s: float = 0.05  # fixed processing time per frame (both modems)
    header_bytes: int = 16  # modem framing (preamble, address, CRC) on top of the message
    queue_frames: int = 8  # frames that may wait behind the one on the channel
    # at most one waiting frame per stream: a newer message of a stream whose frame still
    # waits is dropped (counted as queue), so a slow channel carries recent samples instead
    # of a growing backlog; false: a plain FIFO of queue_frames
    one_per_stream: bool = True
    shipping: float = 0.5  # shipping activity in [0, 1] (noise)
    wind_mps: float = 0.0  # surface wind speed (noise)

    def __post_init__(self) -> None:
        _within("sound_speed_mps", self.sound_speed_mps, 1400.0, 1600.0, "m/s")
        _within("bit_rate_bps", self.bit_rate_bps, 50.0, 100_000.0, "bit/s")
        _within("frequency_khz", self.frequency_khz, 1.0, 100.0, "kHz")
        _within("bandwidth_khz", self.bandwidth_khz, 0.1, 100.0, "kHz")
        _within("source_level_db", self.source_level_db, 100.0, 220.0, "dB re 1 uPa at 1 m")
        _within("spreading_k", self.spreading_k, 1.0, 2.0, "")
        if self.modulation not in ("bpsk", "fsk"):
            raise ConfigValueError(
                "modulation", f"{self.modulation!r} is unknown, expected 'bpsk' or 'fsk'"
            )
        nonneg("modem_latency_s", self.modem_latency_s)
        int_range("header_bytes", self.header_bytes, 0, 1024)
        int_range("queue_frames", self.queue_frames, 1, 10_000)
        probability("shipping", self.shipping)
        _within("wind_mps", self.wind_mps, 0.0, 60.0, "m/s")
        if self.frequency_khz - self.bandwidth_khz / 2 <= 0.0:
            raise ConfigValueError(
                "bandwidth_khz",
                f"{self.bandwidth_khz!r} kHz around {self.frequency_khz!r} kHz reaches 0 Hz, "
                f"expected at most {2 * self.frequency_khz:g} kHz",
            )
        # a binary modulation carries at most one bit per Hz (BPSK), half that for FSK
        per_hz = 1.0 if self.modulation == "bpsk" else 0.5
        top = self.bandwidth_khz * 1000.0 * per_hz
        if self.bit_rate_bps > top:
            raise ConfigValueError(
                "bit_rate_bps",
                f"{self.bit_rate_bps!r} bit/s does not fit a {self.bandwidth_khz:g} kHz band "
                f"with {self.modulation} (at most {top:g} bit/s): widen bandwidth_khz to "
                f"{self.bit_rate_bps / per_hz / 1000:g} kHz or more",
            )

    def frame_s(self, size_bytes: int) -> float:
        """Seconds a message of size_bytes (plus the modem's header) occupies the channel."""
        return 8.0 * (size_bytes + self.header_bytes) / self.bit_rate_bps
