"""The one-way delay meter (both ends of the command link): median and MAD jitter of the last
delays."""

from __future__ import annotations

import numpy as np
import pytest

from common.control.delay import DelayMeter


def test_a_constant_delay_is_measured_exactly_from_the_first_sample() -> None:
    m = DelayMeter(31)
    assert (m.delay_s, m.jitter_s, m.count) == (0.0, 0.0, 0)
    for k in range(1, 50):
        m.add(1.0)
        assert (m.delay_s, m.jitter_s, m.count) == (1.0, 0.0, k)


def test_one_outlier_moves_neither_figure() -> None:
    # a full window of 0.5 s +- 50 ms, then the same with its oldest sample replaced by a
    # command a minute late (a mean over the window would move by ~1.9 s)
    rng = np.random.default_rng(3)
    samples = [float(x) for x in 0.5 + 0.05 * rng.standard_normal(31)]
    clean, hit = DelayMeter(31), DelayMeter(31)
    for d in samples:
        clean.add(d)
    for d in [60.0, *samples[1:]]:
        hit.add(d)
    ranks = sorted(samples)
    assert clean.delay_s == ranks[15]
    # an order statistic moves by at most one rank
    assert ranks[14] <= hit.delay_s <= ranks[16]
    assert abs(hit.delay_s - clean.delay_s) < 0.01
    assert hit.jitter_s == pytest.approx(clean.jitter_s, rel=0.2)


def test_the_jitter_is_the_standard_deviation_of_normal_jitter() -> None:
    # 1.0 s +- 0.2 s (normal), 2001 samples: the MAD estimate's std is ~1.17 sigma / sqrt(n)
    # = 5 ms, so 20 ms is 4 of them
    rng = np.random.default_rng(7)
    m = DelayMeter(2001)
    for d in 1.0 + 0.2 * rng.standard_normal(2001):
        m.add(float(d))
    assert m.delay_s == pytest.approx(1.0, abs=0.02)
    assert m.jitter_s == pytest.approx(0.2, abs=0.02)


def test_it_follows_a_step_in_the_delay_within_half_a_window() -> None:
    m = DelayMeter(31)
    for _ in range(31):
        m.add(0.2)
    for k in range(1, 17):
        m.add(1.0)
        assert m.delay_s == (1.0 if k >= 16 else 0.2)


def test_a_window_must_hold_a_sample() -> None:
    with pytest.raises(ValueError, match="window"):
        DelayMeter(0)


def test_copies_of_one_message_are_one_sample() -> None:
    # a flood of forged copies of a frame stamped at 10 s, arriving ever later: with stamps,
    # only the first copy counts and the median stays at the link's 50 ms
    m = DelayMeter(31)
    for k in range(31):
        assert m.add(0.05, stamp=k * 0.05)
    for i in range(1000):
        assert not m.add(0.5 + i * 0.01, stamp=30 * 0.05)  # a copy of the last one sampled
    assert (m.delay_s, m.jitter_s, m.count, m.copies) == (0.05, 0.0, 31, 1000)
    # a stamp that has left the window is new again (a window's worth of messages ago)
    for k in range(31, 62):
        m.add(0.05, stamp=k * 0.05)
    assert m.add(0.05, stamp=0.0)
