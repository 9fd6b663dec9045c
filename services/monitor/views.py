"""How `tidelink monitor` shows what it watches: JSON lines for scripts, a rich dashboard for
people (one panel per run and vehicle, side by side)."""

from __future__ import annotations

import json
import math
import sys
import time
from typing import IO, Any

from common.jsonsafe import json_safe
from services.monitor.state import Event, RunState


class JsonLinesView:
    """One JSON object per line on `out`: {"type": "event"|"update"|"notice", ...}."""

    def __init__(self, out: IO[str]) -> None:
        self.out = out

    def _write(self, obj: dict[str, Any]) -> None:
        # NaN/inf are not JSON: a value a script cannot parse is worse than null
        self.out.write(json.dumps(json_safe(obj), allow_nan=False) + "\n")
        self.out.flush()

    def notice(self, text: str) -> None:
        self._write({"type": "notice", "wall": time.time(), "text": text})

    def event(self, state: RunState, ev: Event) -> None:
        self._write(
            {
                "type": "event",
                "wall": ev.wall,
                "run": state.run,
                "vehicle": state.vehicle,
                "event": ev.kind,
                "text": ev.text,
                **ev.data,
            }
        )

    def update(self, states: list[RunState], now: float) -> None:
        for s in states:
            self._write({"type": "update", "wall": now, **s.snapshot(now)})

    def close(self) -> None:
        self.out.flush()


class DashboardView:
    """A live terminal dashboard (rich): a panel per run, events scrolling above."""

    MAX_EVENTS = 8

    def __init__(self, out: IO[str] | None = None) -> None:
        from rich.console import Console
        from rich.live import Live

        self.console = Console(file=out or sys.stdout)
        self.live = Live(console=self.console, refresh_per_second=4, transient=False)
        self.events: list[str] = []
        self.live.start()

    def notice(self, text: str) -> None:
        self.console.print(f"[dim]{time.strftime('%H:%M:%S')}[/] {text}", highlight=False)

    def event(self, state: RunState, ev: Event) -> None:
        stamp = time.strftime("%H:%M:%S", time.localtime(ev.wall))
        line = f"{stamp} {state.run}/{state.vehicle}: {ev.text}"
        self.events = (self.events + [line])[-self.MAX_EVENTS :]

    def update(self, states: list[RunState], now: float) -> None:
        from rich.columns import Columns
        from rich.console import Group
        from rich.text import Text

        panels = [_panel(s.snapshot(now)) for s in states]
        log = Text("\n".join(self.events) or "(no events yet)", style="dim")
        self.live.update(Group(Columns(panels, equal=True, expand=True), log))

    def close(self) -> None:
        self.live.stop()


def _num(v: float | None, fmt: str = ".2f", unit: str = "") -> str:
    return "-" if v is None else f"{v:{fmt}}{unit}"


def _ms_pair(a: float | None, b: float | None) -> str:
    if a is None or b is None:
        return "-"
    return f"{a * 1e3:.0f}/{b * 1e3:.0f} ms"


def _mode(mode: str | None) -> str:
    """A vehicle mode, coloured by how much it needs attention."""
    style = {"RUN": "green", "HOLD": "yellow", "FAILSAFE": "bold red"}.get(mode or "", "")
    return f"[{style}]{mode}[/]" if style else (mode or "-")


def _path(path: dict[str, Any] | None) -> str:
    """The path in force: status, id, replans, the strategy that made it (after those
    rejected) and why (a NO_PATH's reason)."""
    if path is None:
        return "-"
    why = f"  ({path['reason']})" if path["reason"] else ""
    made = f"  by {path['strategy']}" if path["strategy"] else ""
    made += f" after {', '.join(path['rejected'])}" if path["rejected"] else ""
    return f"{path['status']} #{path['path_id']}  {path['replans']} replans{made}{why}"


def _plans(path: dict[str, Any] | None) -> str:
    """The paths seen by the strategy that made them, most first."""
    by = sorted((path or {}).get("strategies", {}).items(), key=lambda kv: (-kv[1], kv[0]))
    return "  ".join(f"{code} {n}" for code, n in by) or "-"


def _panel(snap: dict[str, Any]) -> Any:
    """One run's panel: vehicle, services, streams, links and alarms."""
    from rich.console import Group
    from rich.panel import Panel
    from rich.table import Table

    head = Table.grid(padding=(0, 2))
    head.add_column(style="bold")
    head.add_column()
    fleet = snap.get("vehicles")
    if not fleet:  # the run's only vehicle
        head.add_row("mode", _mode(snap["mode"]))
        p = snap["pose"]
        head.add_row(
            "pose",
            "-"
            if p is None
            else f"x {p['x']:.1f} m  y {p['y']:.1f} m  hdg {math.degrees(p['theta']):.0f}°",
        )
        head.add_row("speed", _num(snap["speed_mps"], ".2f", " m/s"))
        head.add_row("to goal", _num(snap["to_goal_m"], ".1f", " m"))
        head.add_row("path", _path(snap["path"]))
        head.add_row("plans by", _plans(snap["path"]))
        head.add_row("estimate error", _num(snap["est_error_m"], ".2f", " m"))
    head.add_row("mission time", _num(snap["t_mission"], ".1f", " s"))
    if snap.get("copies_lost"):
        head.add_row("copies lost", f"[yellow]{snap['copies_lost']}[/] (this monitor fell behind)")
    if snap["end"] is not None:
        head.add_row("ended", f"{snap['end']['reason']} at t={snap['end']['t_end_s']:.1f} s")

    # a fleet: a row per vehicle
    vehicles = Table("vehicle", "mode", "speed", "to goal", "est. err", "path", box=None)
    for vid, v in (fleet or {}).items():
        vehicles.add_row(
            vid,
            _mode(v["mode"]),
            _num(v["speed_mps"], ".2f", " m/s"),
            _num(v["to_goal_m"], ".1f", " m"),
            _num(v["est_error_m"], ".2f", " m"),
            _path(v["path"]),
        )

    services = Table("service", "state", "since", "restarts", box=None, pad_edge=False)
    for name, sv in snap["services"].items():
        color = {"up": "green", "gone": "red", "restarted": "yellow"}[sv["state"]]
        since = time.strftime("%H:%M:%S", time.localtime(sv["since"]))
        services.add_row(name, f"[{color}]{sv['state']}[/]", since, str(sv["restarts"]))

    streams = Table("stream", "age", "count", box=None, pad_edge=False)
    for key, st in snap["streams"].items():
        streams.add_row(key, f"{st['age_s']:.1f} s", str(st["count"]))

    links = Table("link", "sent", "deliv.", "lost", "model p50/p95", "measured p50/p95", box=None)
    for name, ln in snap["links"].items():
        links.add_row(
            name,
            str(ln.get("sent", "-")),
            str(ln.get("delivered", "-")),
            str(ln.get("lost", "-")),
            _ms_pair(ln.get("modelled_p50_s"), ln.get("modelled_p95_s")),
            _ms_pair(ln.get("measured_p50_s"), ln.get("measured_p95_s")),
        )
    alarms = snap["alarms"]
    alarm_text = "\n".join(f"[bold red]! {a}[/]" for a in alarms) or "[green]no alarms[/]"
    parts: list[Any] = [head, "", *([vehicles, ""] if fleet else []), services, "", streams]
    body = Group(*parts, "", links, "", alarm_text)
    return Panel(body, title=f"{snap['run']}/{snap['vehicle']}", border_style="blue")
