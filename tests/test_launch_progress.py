"""`tidelink launch --progress-every`: how often plain progress lines come, and what is refused."""

from __future__ import annotations

import io

import pytest

from services.cli import build_parser
from services.launcher.progress import PlainDisplay, make_display


class _View:
    """The one thing a plain display asks of the mission's view."""

    def summary(self, t_sim: float) -> str:
        return f"t={t_sim:.1f} s of 10 s"


def _launch(*args: str) -> float:
    a = build_parser().parse_args(["launch", "configs/default.toml", *args])
    return float(a.progress_every)


def test_progress_lines_come_every_so_many_seconds() -> None:
    assert _launch() == 2.0 and _launch("--progress-every", "0.25") == 0.25
    out = io.StringIO()
    slow = make_display(out, every_s=3600.0)
    assert isinstance(slow, PlainDisplay)
    for t in (1.0, 2.0, 3.0):
        slow.update(_View(), t)  # type: ignore[arg-type]
    assert out.getvalue().count("launch: t=") == 1  # the first, then none within the hour
    out = io.StringIO()
    fast = make_display(out, every_s=1e-9)
    for t in (1.0, 2.0, 3.0):
        fast.update(_View(), t)  # type: ignore[arg-type]
    assert out.getvalue().count("launch: t=") == 3


@pytest.mark.parametrize("bad", ["0", "-1", "nan", "soon"])
def test_a_bad_interval_is_refused_by_name(bad: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        _launch("--progress-every", bad)
    assert exc.value.code == 2
    assert f"--progress-every: {bad!r} is not a number of seconds > 0" in capsys.readouterr().err
