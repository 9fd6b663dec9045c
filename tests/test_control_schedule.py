"""Schedule.pieces_between: the same pieces, the same floats, as transitions_between and vw_at."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from common.control import Schedule

# times on a coarse grid (many ties: starts repeated, HOLD / FAILSAFE at a start or a bound)
# or anywhere, so both the all-RUN span and the general one are reached
_grid = st.integers(-4, 40).map(lambda k: 0.25 * k)
_time = _grid | st.floats(-1.0, 10.0, allow_nan=False)
_speed = st.floats(-2.0, 3.0, allow_nan=False)


def _pieces_as_first_written(
    sched: Schedule, t_a: float, t_b: float
) -> list[tuple[float, float, float]]:
    """The planner's pieces before pieces_between: the sorted, distinct transitions, then t_b,
    each piece's command looked up with vw_at at its start."""
    cuts = sched.transitions_between(t_a, t_b)
    if len(cuts) > 1:
        cuts = sorted(set(cuts))
    cuts.append(t_b)
    out, t = [], t_a
    for c in cuts:
        out.append((c, *sched.vw_at(t)))
        t = c
    return out


@st.composite
def _schedules(draw: st.DrawFn) -> Schedule:
    """A schedule before any command, or with sorted starts (repeats allowed) and HOLD /
    FAILSAFE anywhere (also before the last start, or FAILSAFE before HOLD)."""
    starts = sorted(draw(st.lists(_time, min_size=0, max_size=12)))
    if not starts:
        return Schedule(idle_v=draw(_speed))
    n = len(starts)
    return Schedule(
        starts=tuple(starts),
        vs=tuple(draw(st.lists(_speed, min_size=n, max_size=n))),
        ws=tuple(draw(st.lists(_speed, min_size=n, max_size=n))),
        t_hold=draw(_time | st.just(math.inf)),
        t_fail=draw(_time | st.just(math.inf)),
        decel=draw(st.sampled_from([math.inf, 0.5, 2.0])),
        v_floor=draw(st.sampled_from([0.0, 0.3])),
    )


@settings(max_examples=300, deadline=None)
@given(sched=_schedules(), t_a=_time, t_b=_time)
def test_pieces_between_is_transitions_between_then_vw_at_to_the_bit(
    sched: Schedule, t_a: float, t_b: float
) -> None:
    got = sched.pieces_between(t_a, t_b)
    expected = _pieces_as_first_written(sched, t_a, t_b)
    # repr tells -0.0 from 0.0: the same floats, not merely equal ones
    assert repr(got) == repr(expected)
