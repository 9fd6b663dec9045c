"""The fault matrix: what to do to a run, to which process or key, and what must hold."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Kind = Literal[
    "kill", "stop", "inject", "kill_launcher", "watchers", "duplicate", "replay", "forge_tick"
]
ROUTER = "router"
# the faults from outside the loop (services/chaos/outside.py): none may touch the run
OUTSIDE: tuple[Kind, ...] = ("watchers", "duplicate", "replay", "forge_tick")
WATCHERS_STOP_S = 20.0  # wall seconds a monitor and a recorder stay SIGSTOPped together
TICK_AHEAD_S = 150.0  # how far ahead (mission seconds) the forged Tick says the clock is

# Hostile or odd-but-valid payloads the injector sends on every data key (forge.py)
INJECTIONS = (
    "malformed",  # not MessagePack at all
    "oversized",  # 20 MB of it
    "non_finite",  # every float field NaN (the decoder rejects it)
    "extreme",  # every float field 1e300, finite: it passes the decoder
    "future",  # stamped 10^6 s ahead of the run
    "unix",  # stamped in Unix time (1.79e9 s), a wrong clock
    "seq_jump",  # a seq of 2^62 from the stream's own publisher name
    "flood",  # 50k copies of a real frame, as fast as the bus takes them
    "hostile",  # all of the cheap ones above together, each round
)


@dataclass(frozen=True)
class Fault:
    """One row of the matrix. `target`: a service (or the router) for kill/stop, the mode
    for inject, the service to start twice for duplicate; `restart`: the launch restarts the
    target on failure; `hold_s`: how long a stopped process stays stopped (mission seconds;
    watchers: wall seconds), or how far ahead a forged Tick is (mission seconds)."""

    kind: Kind
    target: str = ""
    restart: bool = False
    hold_s: float = 8.0

    @property
    def name(self) -> str:
        if self.kind == "kill_launcher":
            return "sigkill launcher"
        if self.kind == "inject":
            return f"inject {self.target}"
        if self.kind == "watchers":
            return f"sigstop {self.hold_s:g}s monitor+record"
        if self.kind == "duplicate":
            return f"duplicate {self.target}"
        if self.kind == "replay":
            return "replay into the run"
        if self.kind == "forge_tick":
            return f"forged tick +{self.hold_s:g}s"
        verb = "sigkill" if self.kind == "kill" else f"sigstop {self.hold_s:g}s"
        return f"{verb} {self.target}" + (" +restart" if self.restart else "")

    @property
    def survivable(self) -> bool:
        """Whether the mission must still succeed (goal, no contact): everything but a
        process killed for good (the run then fails, saying which, metrics written)."""
        return self.kind in ("stop", "inject", *OUTSIDE) or (self.kind == "kill" and self.restart)


def matrix(services: tuple[str, ...]) -> list[Fault]:
    """Every fault: each service and the router killed (services also with a restart) and
    stopped, and each service started twice; each injection on every data key; a forged
    Tick; the watchers frozen; a replay into the run; the launcher killed."""
    rows: list[Fault] = []
    for s in services:
        rows += [Fault("kill", s), Fault("kill", s, restart=True), Fault("stop", s)]
    rows += [Fault("kill", ROUTER), Fault("kill", ROUTER, restart=True)]
    rows.append(Fault("stop", ROUTER, hold_s=4.0))
    rows += [Fault("inject", mode) for mode in INJECTIONS]
    rows.append(Fault("forge_tick", hold_s=TICK_AHEAD_S))
    rows += [Fault("duplicate", s) for s in services]
    rows += [Fault("watchers", hold_s=WATCHERS_STOP_S), Fault("replay")]
    rows.append(Fault("kill_launcher"))
    return rows
