"""`tidelink chaos`: the standing fault matrix on real launches, as a table."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from services.cli.flags import Subparsers, command, scenario_args


def cmd_chaos(a: argparse.Namespace) -> int:
    """run the fault matrix on real launches and print fault x outcome

    Each case launches the scenario (realtime), applies one fault at --fault-at mission seconds
    — a service or the router SIGKILLed (services also with a restart) or SIGSTOPped, hostile
    frames on every data key, the launcher SIGKILLed — and judges the outcome: no hang, no
    process left, metrics written, exit 0 only on success, and success where the fault is
    survivable. Exit 1 if any case failed."""
    from services.chaos.case import CaseSetup
    from services.chaos.run import run_matrix, select
    from services.chaos.verdict import problems, table

    setup = CaseSetup(
        scenario=a.scenario,
        sets=tuple(a.overrides),
        time_scale=a.time_scale,
        fault_at_s=a.fault_at,
    )
    faults = select(setup, a.only)
    if not faults:
        raise ValueError(f"--only {a.only!r} matches no fault; see tidelink chaos --list")
    if a.list:
        for f in faults:
            print(f.name)
        return 0
    outcomes = run_matrix(setup, faults, a.out, lambda s: print(s, file=sys.stderr, flush=True))
    print(table(outcomes))
    failed = [o for o in outcomes if problems(o)]
    print(f"{len(outcomes) - len(failed)} of {len(outcomes)} passed; details: {a.out}/chaos.json")
    return 1 if failed else 0


def register(sub: Subparsers) -> None:
    """Add chaos to the tidelink parser."""
    c = command(sub, "chaos", cmd_chaos)
    scenario_args(c)
    c.add_argument("--only", default=None, metavar="REGEX", help="the faults whose name matches")
    c.add_argument("--list", action="store_true", help="list the faults and exit")
    c.add_argument("--time-scale", type=float, default=4.0, help="realtime speed-up (default 4)")
    c.add_argument(
        "--fault-at", type=float, default=15.0, help="mission second the fault strikes (15)"
    )
    c.add_argument("--out", type=Path, default=Path("runs/chaos"), help="case folders (runs/chaos)")
