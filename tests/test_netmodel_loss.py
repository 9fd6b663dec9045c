"""Loss processes against theory: Bernoulli rate, Gilbert-Elliott stationary rate and bursts."""

import math

from common.config.network import LinkProfile
from common.netmodel import CounterRng, LinkModel
from common.netmodel.rng import U_GE_STATE, U_LOSS

LINK = "planner/cmd->vehicle"
Z999 = 3.29  # two-sided 99.9 % normal quantile


def _loss_flags(profile: LinkProfile, n: int, seed: int) -> tuple[list[bool], LinkModel]:
    m = LinkModel(profile, seed=seed, link=LINK)
    flags = [m.decide(k, k * 1e-3, 100).drop_cause == "loss" for k in range(n)]
    return flags, m


def _runs(flags: list[bool]) -> list[int]:
    runs: list[int] = []
    cur = 0
    for f in flags:
        if f:
            cur += 1
        elif cur:
            runs.append(cur)
            cur = 0
    if cur:
        runs.append(cur)
    return runs


def test_bernoulli_loss_rate() -> None:
    # N = 100000 independent Bernoulli(p): the rate is p within 3.29 * sqrt(p(1-p)/N) (99.9 %)
    n = 100_000
    for p in (0.01, 0.1, 0.5):
        flags, m = _loss_flags(LinkProfile(loss="bernoulli", loss_p=p), n, seed=11)
        rate = sum(flags) / n
        assert abs(rate - p) < Z999 * math.sqrt(p * (1 - p) / n), (p, rate)
        snap = m.stats.snapshot()
        assert snap.dropped_loss == sum(flags)
        assert snap.sent == n and snap.delivered == n - snap.dropped_loss


def test_bernoulli_extremes_are_exact() -> None:
    flags0, _ = _loss_flags(LinkProfile(loss="bernoulli", loss_p=0.0), 5000, seed=1)
    flags1, _ = _loss_flags(LinkProfile(loss="bernoulli", loss_p=1.0), 5000, seed=1)
    assert not any(flags0) and all(flags1)


def test_gilbert_elliott_stationary_loss_rate() -> None:
    # Stationary P(bad) pi_B = p_gb / (p_gb + p_bg); loss rate r = pi_G h_G + pi_B h_B.
    # Losses are correlated through the chain, so the variance of the observed rate over N
    # messages is (asymptotically) [pi_G h_G(1-h_G) + pi_B h_B(1-h_B)
    #   + (h_B - h_G)^2 pi_B pi_G (1 + lam) / (1 - lam)] / N, lam = 1 - p_gb - p_bg the
    # chain's second eigenvalue (per-state Bernoulli noise plus the autocorrelated state term).
    # Bound: 99.9 % normal approximation.
    p_gb, p_bg, h_g, h_b = 0.05, 0.25, 0.02, 0.8
    n = 100_000
    prof = LinkProfile(
        loss="gilbert_elliott", ge_p_gb=p_gb, ge_p_bg=p_bg, ge_loss_good=h_g, ge_loss_bad=h_b
    )
    flags, _ = _loss_flags(prof, n, seed=5)
    pi_b = p_gb / (p_gb + p_bg)
    pi_g = 1 - pi_b
    lam = 1 - p_gb - p_bg
    expected = pi_g * h_g + pi_b * h_b  # 0.15
    var1 = (
        pi_g * h_g * (1 - h_g)
        + pi_b * h_b * (1 - h_b)
        + (h_b - h_g) ** 2 * pi_b * pi_g * (1 + lam) / (1 - lam)
    )
    rate = sum(flags) / n
    assert abs(rate - expected) < Z999 * math.sqrt(var1 / n), (rate, expected)


def test_gilbert_elliott_mean_burst_length() -> None:
    # Classic Gilbert channel (h_G = 0, h_B = 1): a loss burst is a sojourn in the bad state,
    # geometric with mean 1/p_bg and variance (1 - p_bg)/p_bg^2; bursts are independent, so
    # the mean over M bursts is within 3.29 * sqrt(var / M) of 1/p_bg (99.9 %).
    p_gb, p_bg = 0.02, 0.25
    n = 100_000
    prof = LinkProfile(
        loss="gilbert_elliott", ge_p_gb=p_gb, ge_p_bg=p_bg, ge_loss_good=0.0, ge_loss_bad=1.0
    )
    flags, m = _loss_flags(prof, n, seed=9)
    runs = _runs(flags)
    mean = sum(runs) / len(runs)
    var = (1 - p_bg) / p_bg**2
    assert abs(mean - 1 / p_bg) < Z999 * math.sqrt(var / len(runs)), (mean, len(runs))
    # and the expected number of bursts N pi_B p_bg is matched to within 10 %
    pi_b = p_gb / (p_gb + p_bg)
    assert abs(len(runs) / (n * pi_b * p_bg) - 1) < 0.1
    snap = m.stats.snapshot()
    assert snap.loss_bursts == len(runs)
    assert snap.max_loss_burst == max(runs)


def test_gilbert_elliott_matches_a_reference_chain_exactly() -> None:
    # the model's verdicts equal a direct simulation of the chain from the same draws
    p_gb, p_bg, h_g, h_b = 0.1, 0.3, 0.05, 0.7
    prof = LinkProfile(
        loss="gilbert_elliott", ge_p_gb=p_gb, ge_p_bg=p_bg, ge_loss_good=h_g, ge_loss_bad=h_b
    )
    flags, _ = _loss_flags(prof, 3000, seed=21)
    rng = CounterRng(seed=21, link=LINK)
    bad = False
    ref: list[bool] = []
    for k in range(3000):
        u = rng.uniforms(k)
        if k == 0:
            bad = u[U_GE_STATE] < p_gb / (p_gb + p_bg)  # stationary start
        else:
            bad = u[U_GE_STATE] >= p_bg if bad else u[U_GE_STATE] < p_gb
        ref.append(u[U_LOSS] < (h_b if bad else h_g))
    assert flags == ref
