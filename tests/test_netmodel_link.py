"""LinkModel: FIFO, bandwidth queue, outages, duplication, determinism and statistics."""

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from common.config.network import LinkOverride, LinkProfile, NetworkConfig, Outage
from common.netmodel import Decision, LinkModel, NetworkModel

LINK = "planner/cmd->vehicle"
Z999 = 3.29  # two-sided 99.9 % normal quantile


def _us(t: float) -> float:
    return round(t * 1e6) / 1e6


# ---------------------------------------------------------------- FIFO and reordering

_jittery = st.builds(
    lambda kind, scale, dup, bw, loss_p: LinkProfile(
        delay_s=scale if kind == "uniform" else 0.0,
        jitter=kind,
        jitter_s=scale,
        duplicate_p=dup,
        bandwidth_bps=bw,
        queue_len=4,
        loss="bernoulli",
        loss_p=loss_p,
        fifo=True,
    ),
    kind=st.sampled_from(["normal", "uniform", "exponential", "pareto"]),
    scale=st.floats(min_value=1e-4, max_value=0.5),
    dup=st.floats(min_value=0.0, max_value=1.0),
    bw=st.sampled_from([0.0, 1e4, 1e6]),
    loss_p=st.floats(min_value=0.0, max_value=0.5),
)


@settings(max_examples=150, deadline=None)
@given(
    profile=_jittery,
    seed=st.integers(0, 2**32),
    gaps_us=st.lists(st.integers(0, 50_000), min_size=1, max_size=200),
    size=st.integers(0, 2000),
)
def test_fifo_never_reorders(
    profile: LinkProfile, seed: int, gaps_us: list[int], size: int
) -> None:
    m = LinkModel(profile, seed=seed, link=LINK)
    t_us = 0
    last = -math.inf
    for k, gap in enumerate(gaps_us):
        t_us += gap
        d = m.decide(k, t_us / 1e6, size)
        # checked for every message, so a run where everything is dropped still tests something
        assert len(d.delivered_at) <= 2 and (d.drop_cause is None) == bool(d.delivered_at)
        for a in d.delivered_at:  # copies in arrival order, then later messages
            assert a >= last
            assert a >= t_us / 1e6
            last = a


def test_without_fifo_large_jitter_reorders() -> None:
    prof = LinkProfile(delay_s=0.0, jitter="exponential", jitter_s=0.1, fifo=False)
    m = LinkModel(prof, seed=1, link=LINK)
    arrivals = [m.decide(k, k / 1000, 10).delivered_at[0] for k in range(1000)]
    inversions = sum(1 for a, b in zip(arrivals, arrivals[1:], strict=False) if b < a)
    assert inversions > 100  # mean jitter 100x the send period: reordering is the rule


# ---------------------------------------------------------------- bandwidth queue


def _periodic(profile: LinkProfile, period_us: int, size: int, n: int) -> list[Decision]:
    m = LinkModel(profile, seed=0, link=LINK)
    return [m.decide(k, k * period_us / 1e6, size) for k in range(n)]


def test_queue_never_drops_below_capacity() -> None:
    # 1000 B every 10 ms on 1 Mbit/s = 80 % load: every message leaves after exactly its
    # 8 ms serialisation, even with room for a single waiting message
    prof = LinkProfile(bandwidth_bps=1e6, queue_len=1)
    ds = _periodic(prof, 10_000, 1000, 50_000)
    assert all(d.drop_cause is None for d in ds)
    assert all(
        d.delivered_at[0] == pytest.approx(k * 0.01 + 0.008, abs=1e-9) for k, d in enumerate(ds)
    )


@pytest.mark.parametrize("queue_len", [1, 8, 64])
def test_queue_drop_rate_above_capacity(queue_len: int) -> None:
    # 1000 B every 5 ms offered on 1 Mbit/s (offered 1.6 Mbit/s): the transmitter is busy from the
    # first message on, so over N messages it accepts N*T/ser +- (queue_len + 2) of them
    # (what is in service or waiting at the end); drop rate -> 1 - bw/offered = 0.375.
    n = 40_000
    prof = LinkProfile(bandwidth_bps=1e6, queue_len=queue_len)
    ds = _periodic(prof, 5_000, 1000, n)
    drop_rate = sum(d.drop_cause == "queue" for d in ds) / n
    assert abs(drop_rate - (1 - 1e6 / 1.6e6)) <= (queue_len + 2) / n
    delivered = [d.delivered_at[0] for d in ds if d.delivered_at]
    gaps = [b - a for a, b in zip(delivered, delivered[1:], strict=False)]
    assert min(gaps) >= 0.008 - 2e-6  # back-to-back transmissions, never faster than the link


def test_queue_boundary_a_message_starting_now_is_no_longer_waiting() -> None:
    # 1024 B at 8192 bit/s = exactly 1 s per message (binary fractions, no rounding).
    # t=0: in service until 1; t=0.5: waits (queue full); t=0.9: dropped; t=1.0: the waiting
    # message starts right now, so the queue has room again; it leaves at 3.
    m = LinkModel(LinkProfile(bandwidth_bps=8192.0, queue_len=1), seed=0, link=LINK)
    got = [m.decide(k, t, 1024) for k, t in enumerate((0.0, 0.5, 0.9, 1.0))]
    assert [d.delivered_at for d in got] == [(1.0,), (2.0,), (), (3.0,)]
    assert got[2].drop_cause == "queue"


@settings(max_examples=100, deadline=None)
@given(
    arrivals=st.lists(
        st.tuples(st.integers(0, 20_000), st.integers(1, 3000)), min_size=1, max_size=150
    ),
    queue_len=st.integers(1, 5),
)
def test_queue_matches_a_reference_transmitter(
    arrivals: list[tuple[int, int]], queue_len: int
) -> None:
    # reference: drop iff queue_len accepted messages have not started transmission yet
    bw = 1e6
    m = LinkModel(LinkProfile(bandwidth_bps=bw, queue_len=queue_len), seed=0, link=LINK)
    starts: list[float] = []
    busy = 0.0
    t_us = 0
    for k, (gap, size) in enumerate(arrivals):
        t_us += gap
        t = t_us / 1e6
        d = m.decide(k, t, size)
        if sum(1 for s in starts if s > t) >= queue_len:
            assert d.drop_cause == "queue"
            continue
        start = max(t, busy)
        busy = start + size * 8 / bw
        starts.append(start)
        assert d.delivered_at == (_us(busy),)


# ---------------------------------------------------------------- outages


def test_link_outage_delivers_nothing_inside_the_window() -> None:
    prof = LinkProfile(delay_s=0.05, jitter="exponential", jitter_s=0.05, duplicate_p=0.3)
    out = Outage(start_s=2.0, end_s=3.0, link=LINK)
    m = LinkModel(prof, seed=3, link=LINK, outages=(out,))
    n = 5000
    ds = [m.decide(k, k / 1000, 10) for k in range(n)]
    assert all(not (2.0 <= a < 3.0) for d in ds for a in d.delivered_at)
    sent_inside = [d for k, d in enumerate(ds) if 2.0 <= k / 1000 < 3.0]
    assert len(sent_inside) == 1000 and all(d.drop_cause == "outage" for d in sent_inside)
    # after the window the link is whole again: everything sent from t = 3 s is delivered
    assert all(d.delivered_at for d in ds[3000:])
    # the counters agree: only outage drops, at least the 1000 sent inside (plus in-flight ones)
    snap = m.stats.snapshot()
    assert snap.dropped_outage >= 1000 and snap.dropped_loss == snap.dropped_queue == 0
    assert snap.sent == snap.delivered + snap.dropped_outage == n


def test_service_outage_cuts_every_link_touching_the_service() -> None:
    prof = LinkProfile(delay_s=0.02, jitter="uniform", jitter_s=0.02)
    cfg = NetworkConfig(default=prof, outages=(Outage(start_s=1.0, end_s=2.0, service="planner"),))
    net = NetworkModel(cfg, seed=7)
    routes = [
        ("planner", "cmd", "vehicle"),
        ("sensor", "nav", "planner"),
        ("sensor", "nav", "estimator"),
    ]
    got: dict[str, list[Decision]] = {f"{s}/{st_}->{r}": [] for s, st_, r in routes}
    for k in range(3000):
        for s, st_, r in routes:
            got[f"{s}/{st_}->{r}"].append(net.decide(s, st_, r, k, k / 1000, 50))
    for name in ("planner/cmd->vehicle", "sensor/nav->planner"):
        times = [a for d in got[name] for a in d.delivered_at]
        assert times and not any(1.0 <= a < 2.0 for a in times)
        assert net.snapshots()[name].dropped_outage >= 1000
    untouched = net.snapshots()["sensor/nav->estimator"]
    assert untouched.dropped_outage == 0 and untouched.delivered == 3000


def test_permanent_partition() -> None:
    out = Outage(start_s=0.5, end_s=math.inf, service="vehicle")
    m = LinkModel(LinkProfile(delay_s=0.01), seed=0, link=LINK, outages=(out,))
    ds = [m.decide(k, k / 100, 10) for k in range(100)]
    assert all(d.delivered_at and d.delivered_at[0] < 0.5 for d in ds[:49])
    assert all(d.drop_cause == "outage" for d in ds[49:])  # 0.49 + 0.01 lands at the window


# ---------------------------------------------------------------- duplication


def test_duplicate_rate_and_independent_copies() -> None:
    # duplicated fraction within 3.29 * sqrt(p(1-p)/N) of p (99.9 %); with continuous jitter
    # the two copies' delays are independent draws, so they (almost surely) differ
    p, n = 0.2, 40_000
    prof = LinkProfile(delay_s=0.01, jitter="exponential", jitter_s=0.01, duplicate_p=p, fifo=False)
    m = LinkModel(prof, seed=2, link=LINK)
    ds = [m.decide(k, k / 1000, 10) for k in range(n)]
    dups = [d for d in ds if len(d.delivered_at) == 2]
    assert abs(len(dups) / n - p) < Z999 * math.sqrt(p * (1 - p) / n)
    assert sum(d.delivered_at[0] == d.delivered_at[1] for d in dups) < 0.01 * len(dups)
    assert m.stats.snapshot().duplicated == len(dups)


# ---------------------------------------------------------------- determinism

_FULL = LinkProfile(
    delay_s=0.03,
    jitter="pareto",
    jitter_s=0.01,
    loss="gilbert_elliott",
    duplicate_p=0.1,
    fifo=True,
    bandwidth_bps=2e5,
    queue_len=3,
)


def test_same_inputs_give_identical_decisions() -> None:
    outs = (Outage(start_s=1.0, end_s=1.5, service="vehicle"),)
    runs = []
    for seed in (5, 5, 6):
        m = LinkModel(_FULL, seed=seed, link=LINK, outages=outs)
        runs.append([m.decide(k, k / 200, 100 + k % 50) for k in range(3000)])
    assert runs[0] == runs[1]
    assert runs[0] != runs[2]


_STATELESS = LinkProfile(
    delay_s=0.02, jitter="normal", jitter_s=0.01, loss="bernoulli", loss_p=0.3,
    duplicate_p=0.3, fifo=False,
)  # fmt: skip


@given(
    earlier=st.sets(st.integers(0, 999), max_size=30),
    k=st.integers(1000, 2000),
    seed=st.integers(0, 2**64 - 1),
)
def test_stateless_decision_does_not_depend_on_history(
    earlier: set[int], k: int, seed: int
) -> None:
    fresh = LinkModel(_STATELESS, seed=seed, link=LINK).decide(k, k / 100, 10)
    m = LinkModel(_STATELESS, seed=seed, link=LINK)
    for j in sorted(earlier):
        m.decide(j, j / 100, 10)
    assert m.decide(k, k / 100, 10) == fresh


def test_out_of_order_calls_are_rejected() -> None:
    m = LinkModel(LinkProfile(), seed=0, link=LINK)
    m.decide(5, 1.0, 10)
    with pytest.raises(ValueError, match="^seq:"):
        m.decide(5, 1.0, 10)
    with pytest.raises(ValueError, match="^send_time:"):
        m.decide(6, 0.5, 10)
    with pytest.raises(ValueError, match="^size_bytes:"):
        m.decide(7, 1.0, -1)
    with pytest.raises(ValueError, match="^link:"):
        LinkModel(LinkProfile(), seed=0, link="planner->vehicle")


# ---------------------------------------------------------------- statistics


def test_snapshot_counts_and_percentiles() -> None:
    prof = LinkProfile(
        delay_s=0.01, jitter="exponential", jitter_s=0.02, loss="bernoulli", loss_p=0.1,
        duplicate_p=0.05, bandwidth_bps=1e6, queue_len=2, fifo=False,
    )  # fmt: skip
    m = LinkModel(prof, seed=8, link=LINK, outages=(Outage(start_s=3, end_s=4, link=LINK),))
    n = 20_000
    delays: list[float] = []
    for k in range(n):
        t = k / 2000
        d = m.decide(k, t, 100 + (k * 37) % 400)
        if d.delivered_at:
            delays.append(d.delivered_at[0] - t)
    s = m.stats.snapshot()
    assert s.sent == n == s.delivered + s.dropped_loss + s.dropped_outage + s.dropped_queue
    assert min(s.dropped_loss, s.dropped_outage, s.dropped_queue, s.duplicated) > 0
    assert s.delivered == len(delays)
    delays.sort()
    for q, got in ((0.5, s.delay_p50_s), (0.99, s.delay_p99_s)):
        exact = delays[math.ceil(q * len(delays)) - 1]  # nearest rank
        assert abs(got / exact - 1) <= 0.0051  # histogram bins are 1 % wide: centre within 0.5 %
    assert s.delay_mean_s == pytest.approx(sum(delays) / len(delays), rel=1e-9)
    assert s.delay_max_s == pytest.approx(delays[-1], abs=1e-12)


def test_network_model_resolves_profiles_per_link() -> None:
    slow = LinkProfile(delay_s=0.5)
    cfg = NetworkConfig(
        default=LinkProfile(delay_s=0.01), links=(LinkOverride(link="*->vehicle", profile=slow),)
    )
    net = NetworkModel(cfg, seed=0)
    assert net.decide("planner", "cmd", "vehicle", 0, 1.0, 10).delivered_at == (1.5,)
    assert net.decide("sensor", "nav", "estimator", 0, 1.0, 10).delivered_at == (1.01,)
    assert net.link("planner", "cmd", "vehicle") is net.link("planner", "cmd", "vehicle")
    assert list(net.snapshots()) == ["planner/cmd->vehicle", "sensor/nav->estimator"]


@settings(max_examples=100, deadline=None)
@given(
    delay_us=st.integers(0, 500_000),
    seed=st.integers(0, 2**32),
    gaps_us=st.lists(st.integers(0, 50_000), min_size=1, max_size=100),
    size=st.integers(0, 2000),
)
def test_a_constant_delay_link_decides_as_the_whole_pipeline_does(
    delay_us: int, seed: int, gaps_us: list[int], size: int
) -> None:
    # a link with nothing but a constant delay takes a short cut; a zero-width uniform jitter
    # is the same link through every stage of the pipeline (drawn, queued, FIFO)
    fixed = LinkModel(LinkProfile(delay_s=delay_us / 1e6), seed=seed, link=LINK)
    whole = LinkModel(
        LinkProfile(delay_s=delay_us / 1e6, jitter="uniform", jitter_s=0.0), seed=seed, link=LINK
    )
    t_us = 0
    for k, gap in enumerate(gaps_us):
        t_us += gap
        assert fixed.decide(k, t_us / 1e6, size) == whole.decide(k, t_us / 1e6, size)
    assert fixed.stats.snapshot() == whole.stats.snapshot()
