"""The acoustic medium against published figures: absorption, delay, serialization, errors."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given
from hypothesis import strategies as st

from common.config.acoustic import AcousticMedium
from common.config.errors import ConfigValueError
from common.netmodel.acoustic import (
    bit_error_rate,
    frame_error_rate,
    noise_psd_db,
    snr_db,
    thorp_absorption_db_per_km,
    transmission_loss_db,
)
from common.netmodel.acoustic_link import AcousticLink
from common.netmodel.modem import Modem

LINK = "planner/cmd->vehicle"
# a medium whose frame errors matter within a few km (the acoustic_range experiment's)
WEAK = AcousticMedium(
    frequency_khz=25.0,
    bandwidth_khz=12.0,
    bit_rate_bps=10_000.0,
    source_level_db=160.0,
    wind_mps=10.0,
)


@pytest.mark.parametrize(
    ("f_khz", "db_per_km"),
    # Thorp's formula as tabulated/plotted by Stojanovic (2007, fig. 1) and Urick
    [(1.0, 0.069), (10.0, 1.19), (25.0, 6.10)],
)
def test_thorp_absorption_matches_the_published_values(f_khz: float, db_per_km: float) -> None:
    assert thorp_absorption_db_per_km(f_khz) == pytest.approx(db_per_km, rel=0.01)


def test_transmission_loss_is_spreading_plus_absorption() -> None:
    # 1 km at 10 kHz, practical spreading: 1.5 * 10 log10(1000) + 1 km * 1.187 dB/km
    assert transmission_loss_db(1000.0, 10.0, 1.5) == pytest.approx(45.0 + 1.187, abs=0.01)
    assert transmission_loss_db(0.0, 10.0, 1.5) == pytest.approx(0.0, abs=0.01)  # from 1 m


def test_noise_falls_with_frequency_in_the_band_modems_use() -> None:
    # Stojanovic (2007, fig. 2): the spectrum decays across 1-100 kHz (wind, then thermal)
    psd = [noise_psd_db(f, 0.5, 0.0) for f in (1.0, 10.0, 50.0)]
    assert psd[0] > psd[1] > psd[2]
    assert noise_psd_db(10.0, 0.5, 10.0) > noise_psd_db(10.0, 0.5, 0.0)  # wind adds noise


def test_bit_error_rates_of_binary_modulations() -> None:
    # Proakis: BPSK at Eb/N0 = 9.6 dB is ~1e-5; non-coherent FSK needs ~4 dB more
    ebn0 = 10 ** (9.6 / 10)
    assert bit_error_rate("bpsk", ebn0) == pytest.approx(1.0e-5, rel=0.1)
    assert bit_error_rate("fsk", ebn0) > 100 * bit_error_rate("bpsk", ebn0)
    assert bit_error_rate("bpsk", 0.0) == pytest.approx(0.5)


def _link(medium: AcousticMedium, seed: int = 1) -> AcousticLink:
    return AcousticLink(medium, seed=seed, link=LINK, modem=Modem(medium))


def test_a_1500_m_link_takes_1_s_to_propagate() -> None:
    m = AcousticMedium(modem_latency_s=0.0, header_bytes=0, bit_rate_bps=8000.0, bandwidth_khz=8.0)
    d = _link(m).decide(1, 10.0, 100, 1500.0)
    # 100 bytes at 8 kbit/s = 0.1 s on the channel, then 1500 m at 1500 m/s = 1.0 s
    assert d.delivered_at == (pytest.approx(10.0 + 0.1 + 1.0, abs=1e-6),)


def test_serialization_of_a_known_frame() -> None:
    m = AcousticMedium(bit_rate_bps=1000.0, header_bytes=16)
    assert m.frame_s(48) == pytest.approx(0.512)  # (48 + 16) bytes * 8 / 1000 bit/s
    d = _link(m).decide(1, 0.0, 48, 0.0)
    assert d.delivered_at == (pytest.approx(m.modem_latency_s + 0.512, abs=1e-6),)


@given(
    r1=st.floats(10.0, 5000.0),
    dr=st.floats(0.0, 3000.0),
    size=st.integers(0, 2000),
    more=st.integers(0, 2000),
)
def test_frame_errors_grow_with_range_and_frame_size(
    r1: float, dr: float, size: int, more: int
) -> None:
    fer = frame_error_rate(WEAK, r1, size)
    assert 0.0 <= fer <= 1.0
    assert frame_error_rate(WEAK, r1 + dr, size) >= fer
    assert frame_error_rate(WEAK, r1, size + more) >= fer


def test_frame_errors_decide_delivery_at_the_rate_the_budget_gives() -> None:
    # 2.5 km on the weak medium: a 400-byte frame fails ~45 % of the time
    p = frame_error_rate(WEAK, 2500.0, 400)
    assert 0.3 < p < 0.6
    link = _link(dataclasses.replace(WEAK, one_per_stream=False, queue_frames=10_000))
    lost = sum(link.decide(i, i * 10.0, 400, 2500.0).drop_cause == "loss" for i in range(1, 2001))
    assert lost / 2000 == pytest.approx(p, abs=0.04)
    assert snr_db(WEAK, 100.0) > snr_db(WEAK, 2500.0)


def test_a_half_duplex_modem_sends_one_frame_at_a_time_in_order_and_drops_beyond_its_queue() -> (
    None
):
    m = AcousticMedium(
        bit_rate_bps=1000.0,
        header_bytes=0,
        modem_latency_s=0.0,
        queue_frames=2,
        one_per_stream=False,
    )
    link = _link(m)
    # five 125-byte frames (1 s each) offered at once: the first goes, two wait, two drop
    out = [link.decide(i, 0.0, 125, 0.0) for i in range(1, 6)]
    assert [d.delivered_at for d in out[:3]] == [(1.0,), (2.0,), (3.0,)]
    assert [d.drop_cause for d in out[3:]] == ["queue", "queue"]
    assert link.stats.snapshot().dropped_queue == 2


def test_one_waiting_frame_per_stream_keeps_a_slow_channel_fresh() -> None:
    m = AcousticMedium(bit_rate_bps=1000.0, header_bytes=0, modem_latency_s=0.0)
    modem = Modem(m)
    assert modem.offer(("state", 1), 0.0, 125) == 0.0  # on the channel until 1 s
    assert modem.offer(("state", 2), 0.1, 125) == 1.0  # waits
    assert modem.offer(("state", 3), 0.2, 125) is None  # 2 still waits: 3 is dropped
    assert modem.offer(("tracks", 1), 0.3, 125) == 2.0  # another stream queues behind
    assert modem.offer(("state", 4), 1.5, 125) == 3.0  # 2 is on the channel now
    assert modem.dropped == 1


def test_a_message_to_two_receivers_is_one_broadcast_frame() -> None:
    m = AcousticMedium(bit_rate_bps=1000.0, header_bytes=0, modem_latency_s=0.0)
    modem = Modem(m)
    a = AcousticLink(m, seed=1, link="estimator/state->planner", modem=modem)
    b = AcousticLink(m, seed=1, link="estimator/state->monitor", modem=modem)
    da, db = a.decide(1, 0.0, 125, 1500.0), b.decide(1, 0.0, 125, 3000.0)
    assert da.delivered_at == (pytest.approx(2.0),) and db.delivered_at == (pytest.approx(3.0),)
    assert modem.frames == 1


def test_decisions_are_a_function_of_seed_link_and_seq() -> None:
    def run(seed: int) -> list[tuple[float, ...]]:
        link = _link(dataclasses.replace(WEAK, queue_frames=10_000, one_per_stream=False), seed)
        return [link.decide(i, i * 1.0, 300, 2500.0).delivered_at for i in range(1, 200)]

    assert run(1) == run(1) and run(1) != run(2)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("sound_speed_mps", 340.0),
        ("bit_rate_bps", 10.0),
        ("bit_rate_bps", 20_000.0),  # beyond the 5 kHz band with BPSK
        ("frequency_khz", 500.0),
        ("bandwidth_khz", 0.0),
        ("source_level_db", 300.0),
        ("spreading_k", 3.0),
        ("modulation", "qam"),
        ("queue_frames", 0),
        ("shipping", 2.0),
        ("wind_mps", -1.0),
    ],
)
def test_an_out_of_range_medium_names_its_field(field: str, value: object) -> None:
    with pytest.raises(ConfigValueError) as exc:
        AcousticMedium(**{field: value})  # type: ignore[arg-type]
    assert exc.value.key_path == (field,)


def test_a_band_reaching_0_hz_and_fsk_beyond_half_the_band_are_refused() -> None:
    with pytest.raises(ConfigValueError, match="reaches 0 Hz"):
        AcousticMedium(frequency_khz=2.0, bandwidth_khz=5.0, bit_rate_bps=100.0)
    with pytest.raises(ConfigValueError, match="widen bandwidth_khz to 6 kHz"):
        AcousticMedium(modulation="fsk", bit_rate_bps=3000.0)
