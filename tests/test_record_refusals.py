"""A run's record takes a stream's messages only from its publisher with a plausible seq, so
one forged message cannot become a stream's last, fake a lockstep watermark, or overflow a
restarted service's renumbering; the mission's end is judged on credible truth only."""

from __future__ import annotations

from pathlib import Path

from common.config.scenario import load_scenario
from common.messages import TruthState
from common.runtime.model.mission import load_mission, mission_record
from common.runtime.model.record import Record, Renumbering
from common.runtime.model.seqwindow import SeqWindow, max_seq_gap

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"


def _truth(seq: int, x: float, source: str = "vehicle") -> TruthState:
    """The vehicle at (x, 20) at t = seq * 0.05 s, moving east at 1.5 m/s."""
    return TruthState(
        stamp=seq * 0.05, x=x, y=20.0, theta=0.0, v=1.5, w=0.0, source=source, seq=seq
    )


def _cruise(record: Record, n: int, x0: float = 5.0) -> None:
    for k in range(1, n + 1):
        assert record.add("vehicle", "truth", _truth(k, x0 + 0.075 * k)) is None


def test_forged_messages_are_refused_by_reason_and_the_stream_carries_on() -> None:
    record = Record(max_seq_gap=1000)
    _cruise(record, 10)
    goal = dict(x=95.0)
    assert record.add("vehicle", "truth", _truth(2**62, **goal)) == "seq_jump"
    assert record.add("vehicle", "truth", _truth(1011, **goal)) == "seq_jump"  # 10 + 1000 + 1
    assert record.add("vehicle", "truth", _truth(0, **goal)) == "seq_jump"  # never published
    assert record.add("vehicle", "truth", _truth(11, source="planner", **goal)) == "wrong_source"
    assert record.add("vehicle", "truth", _truth(11, source="", **goal)) == "wrong_source"
    assert record.add("vehicle", "truth", _truth(5, **goal)) == "conflict"  # seq 5 is taken
    assert record.add("vehicle", "truth", _truth(5, 5.0 + 0.075 * 5)) is None  # a repeat
    assert record.rejected == {"wrong_source": 2, "seq_jump": 3, "conflict": 1, "future": 0}
    # nothing forged was kept, and the publisher's next messages are taken as before
    _cruise(record, 20)
    last = record.last("vehicle", "truth")
    assert last is not None and last.seq == 20 and record.last_seq("vehicle", "truth") == 20
    assert len(record.stream("vehicle", "truth")) == record.count == 20


def test_renumbering_a_restarted_service_never_overflows_on_a_forged_seq() -> None:
    record = Record()
    renumbering = Renumbering(record)
    _cruise(record, 10)
    renumbering.rejoined("vehicle")  # restarted: its seqs start at 1 again, offset by 10
    recorded = renumbering.add("vehicle", "truth", _truth(1, 5.0))
    assert recorded is not None and recorded.seq == 11
    # 2**63 - 1 + 10 would not fit the wire's seq: left as is, then refused
    assert renumbering.add("vehicle", "truth", _truth(2**63 - 1, 95.0)) is None
    assert record.rejected["seq_jump"] == 1 and record.last_seq("vehicle", "truth") == 11


def test_a_service_back_after_its_session_was_cut_keeps_its_numbering() -> None:
    """The same process rejoining (a router restarted, a host cut off) numbers on: its
    messages are not offset as a restarted one's are; the message that tells is the first."""
    record = Record()
    renumbering = Renumbering(record)
    _cruise(record, 10)
    renumbering.rejoined("vehicle")
    for k in (12, 13, 11):  # one lost in the cut, then one late
        renumbering.add("vehicle", "truth", _truth(k, 5.0 + 0.075 * k))
    assert [m.seq for m in record.stream("vehicle", "truth")] == list(range(1, 14))
    assert record.rejected == dict.fromkeys(record.rejected, 0)


def test_seq_window_prefix_and_gap() -> None:
    w = SeqWindow(max_gap=5)
    for seq in (2, 3, 1, 5):
        assert w.plausible(seq)
        w.take(seq)
    assert (w.prefix, w.highest, w.seen(4), w.seen(5)) == (3, 5, False, True)
    assert w.plausible(10) and not w.plausible(11) and not w.plausible(0)
    w.take(4)
    assert w.prefix == 5


def test_the_default_missions_window_is_what_its_streams_can_publish() -> None:
    s, _ = load_scenario(DEFAULT)
    mission = load_mission(s)
    # 4 x 200 s / 0.05 s (the vehicle's period, the fastest) + 1024
    assert max_seq_gap(mission.dataflow, mission.max_time_s) == 17024
    record = mission_record(mission)
    assert record.add("vehicle", "truth", _truth(17024, 95.0)) is None
    assert record.add("vehicle", "status", _truth(17025, 95.0)) == "seq_jump"


def test_the_end_is_judged_on_credible_truth_only() -> None:
    s, _ = load_scenario(DEFAULT)
    mission = load_mission(s)
    record = mission_record(mission)
    _cruise(record, 20)
    assert mission.observe(record) is None
    # the vehicle's name and the next seq, but 88 m away from its predecessor in 0.05 s
    assert record.add("vehicle", "truth", _truth(21, 95.0)) is None
    assert mission.observe(record) is None
    assert mission.metrics(record).reached_goal is False
    # a state at the goal with no predecessor recorded (seq 23 after the forged 21)
    assert record.add("vehicle", "truth", _truth(23, 95.0)) is None
    assert mission.observe(record) is None
    # the vehicle really arriving: consecutive states 7.5 cm apart
    record = mission_record(mission)
    _cruise(record, 20, x0=93.0)
    assert mission.observe(record) == "goal"
    m = mission.metrics(record)
    assert m.reached_goal is True and m.travel_time_s > 0.0
