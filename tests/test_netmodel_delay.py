"""Delay distributions against closed-form mean and variance; trace replay and parsing."""

import math
from pathlib import Path
from statistics import NormalDist

import pytest
from hypothesis import given
from hypothesis import strategies as st

from common.config.network import LinkProfile
from common.netmodel import DelaySampler, LinkModel, parse_trace

LINK = "sensor/nav->estimator"
N = 50_000
Z999 = 3.29  # two-sided 99.9 % normal quantile


def _delays(profile: LinkProfile, n: int = N, seed: int = 4) -> list[float]:
    # fifo off and unlimited bandwidth: the delivery delay is exactly the drawn delay (to 1 us)
    m = LinkModel(profile, seed=seed, link=LINK)
    out: list[float] = []
    for k in range(n):
        t = k / 1000
        (arrival,) = m.decide(k, t, 100).delivered_at
        out.append(arrival - t)
    return out


def _check_moments(xs: list[float], mean: float, var: float) -> None:
    # Sample mean within 3.29 * sqrt(var/N) of the closed form, sample variance within
    # 3.29 * sqrt((m4 - var^2)/N) (99.9 %, normal approximation; m4 = sample 4th central moment).
    # The 1 us rounding of delivery times adds at most 0.5 us per sample, far below both bounds.
    n = len(xs)
    m = sum(xs) / n
    v = sum((x - m) ** 2 for x in xs) / (n - 1)
    m4 = sum((x - m) ** 4 for x in xs) / n
    assert abs(m - mean) < Z999 * math.sqrt(var / n), ("mean", m, mean)
    assert abs(v - var) < Z999 * math.sqrt((m4 - v * v) / n), ("var", v, var)


def test_constant_delay_is_exact() -> None:
    xs = _delays(LinkProfile(delay_s=0.025, fifo=False), n=1000)
    assert all(abs(x - 0.025) < 1e-9 for x in xs)


def test_normal_jitter_without_truncation() -> None:
    # delay_s = 10 sigma: truncation at 0 removes P < 1e-23, so mean mu and variance sigma^2
    mu, sigma = 0.1, 0.01
    xs = _delays(LinkProfile(delay_s=mu, jitter="normal", jitter_s=sigma, fifo=False))
    _check_moments(xs, mu, sigma**2)


def test_normal_jitter_truncated_at_zero() -> None:
    # truncated normal on [0, inf): alpha = -mu/sigma, lam = phi(alpha)/(1 - Phi(alpha)),
    # mean = mu + sigma*lam, var = sigma^2 (1 + alpha*lam - lam^2)
    mu, sigma = 0.01, 0.02
    xs = _delays(LinkProfile(delay_s=mu, jitter="normal", jitter_s=sigma, fifo=False))
    assert min(xs) >= 0.0
    nd = NormalDist()
    alpha = -mu / sigma
    lam = nd.pdf(alpha) / (1 - nd.cdf(alpha))
    _check_moments(xs, mu + sigma * lam, sigma**2 * (1 + alpha * lam - lam**2))


def test_uniform_jitter() -> None:
    # U(mu - w, mu + w): mean mu, variance w^2/3
    mu, w = 0.05, 0.02
    xs = _delays(LinkProfile(delay_s=mu, jitter="uniform", jitter_s=w, fifo=False))
    assert mu - w - 1e-9 <= min(xs) and max(xs) <= mu + w + 1e-9
    _check_moments(xs, mu, w * w / 3)


def test_exponential_jitter() -> None:
    # mu + Exp(mean m): mean mu + m, variance m^2
    mu, mean = 0.02, 0.03
    xs = _delays(LinkProfile(delay_s=mu, jitter="exponential", jitter_s=mean, fifo=False))
    assert min(xs) >= mu - 1e-9
    _check_moments(xs, mu + mean, mean**2)


def _lomax_raw_moment(k: int, scale: float, shape: float) -> float:
    # E[X^k] = scale^k k! / prod_{i=1..k} (shape - i), for shape > k
    return scale**k * math.factorial(k) / math.prod(shape - i for i in range(1, k + 1))


def test_pareto_jitter_mean_and_variance() -> None:
    # Lomax (Pareto II) jitter: mean s/(a-1), variance s^2 a / ((a-1)^2 (a-2)).
    # The variance test uses shape 6 so the 4th moment (needed by its CLT bound) exists;
    # the mean test also runs at shape 2.5 (finite variance, heavy tail).
    mu, s = 0.01, 0.02
    a = 6.0
    xs = _delays(LinkProfile(delay_s=mu, jitter="pareto", jitter_s=s, pareto_shape=a, fifo=False))
    assert min(xs) >= mu - 1e-9
    var = s * s * a / ((a - 1) ** 2 * (a - 2))
    assert var == pytest.approx(_lomax_raw_moment(2, s, a) - _lomax_raw_moment(1, s, a) ** 2)
    _check_moments(xs, mu + s / (a - 1), var)

    a = 2.5
    xs = _delays(LinkProfile(delay_s=mu, jitter="pareto", jitter_s=s, pareto_shape=a, fifo=False))
    var = s * s * a / ((a - 1) ** 2 * (a - 2))
    m = sum(xs) / len(xs)
    assert abs(m - (mu + s / (a - 1))) < Z999 * math.sqrt(var / len(xs))


@given(u=st.floats(min_value=0.0, max_value=1.0 - 2.0**-53), seq=st.integers(0, 10**6))
def test_every_sampler_is_finite_and_nonnegative(u: float, seq: int) -> None:
    profiles = [
        LinkProfile(delay_s=0.0, jitter="normal", jitter_s=0.05),
        LinkProfile(delay_s=1.0, jitter="normal", jitter_s=1e-6),  # truncation point far out
        LinkProfile(delay_s=0.05, jitter="uniform", jitter_s=0.05),
        LinkProfile(delay_s=0.0, jitter="exponential", jitter_s=0.05),
        LinkProfile(delay_s=0.0, jitter="pareto", jitter_s=0.05, pareto_shape=2.1),
    ]
    for p in profiles:
        d = DelaySampler(p).sample(u, seq, 0)
        assert math.isfinite(d) and d >= 0.0


def test_trace_replays_cyclically_by_seq(tmp_path: Path) -> None:
    path = tmp_path / "delays.csv"
    path.write_text("# measured one-way delays\nseq,delay_s\n0,0.010\n1,0.020\n\n2,0.005\n")
    trace = (0.010, 0.020, 0.005)
    prof = LinkProfile(delay_s=0.001, trace_file=str(path), fifo=False)
    m = LinkModel(prof, seed=0, link=LINK)
    for k in range(0, 20, 2):  # skipped seqs still index the trace by seq
        t = k / 100
        (arrival,) = m.decide(k, t, 10).delivered_at
        assert arrival - t == pytest.approx(0.001 + trace[k % 3], abs=1e-9)


def test_trace_duplicate_takes_the_next_entry() -> None:
    prof = LinkProfile(trace_file="unused.txt", duplicate_p=1.0, fifo=False)
    m = LinkModel(prof, seed=0, link=LINK, trace=(0.03, 0.01, 0.02))
    assert m.decide(0, 0.0, 10).delivered_at == (0.01, 0.03)
    assert m.decide(2, 1.0, 10).delivered_at == (1.02, 1.03)


def test_parse_trace_plain_and_errors() -> None:
    assert parse_trace("0.1\n 0.2 \n#x\n0\n") == (0.1, 0.2, 0.0)
    with pytest.raises(ValueError, match=r"^trace_file: t:3: 'abc'"):
        parse_trace("0.1\n0.2\nabc\n", source="t")
    with pytest.raises(ValueError, match="^trace_file: t:2: delay -0.1"):
        parse_trace("0.1\n-0.1\n", source="t")
    with pytest.raises(ValueError, match="^trace_file: t:1: delay nan"):
        parse_trace("nan\n", source="t")
    with pytest.raises(ValueError, match="holds no delays"):
        parse_trace("delay_s\n# nothing\n", source="t")
