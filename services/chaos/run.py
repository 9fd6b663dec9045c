"""Run the fault matrix (or the cases a pattern selects) and write what came of each."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

from common.config.scenario import load_scenario
from common.runtime.distributed.bringup import run_keys
from common.runtime.model.mission import load_mission
from services.chaos.case import CaseSetup, Outcome, run_case
from services.chaos.faults import Fault, matrix
from services.chaos.verdict import problems


def select(setup: CaseSetup, only: str | None) -> list[Fault]:
    """The matrix of the scenario's mission, narrowed to the faults whose name matches."""
    scenario, _ = load_scenario(setup.scenario, list(setup.sets), None)
    rows = matrix(load_mission(scenario).dataflow.names)
    if only:
        rx = re.compile(only)
        rows = [f for f in rows if rx.search(f.name)]
    return rows


def run_matrix(
    setup: CaseSetup, faults: list[Fault], out: Path, say: Callable[[str], None]
) -> list[Outcome]:
    """Each case in turn into out/<n>-<fault>/; out/chaos.json gets every outcome as it
    comes (a killed matrix keeps what it has measured)."""
    scenario, _ = load_scenario(setup.scenario, list(setup.sets), None)
    keys, flow = run_keys(scenario), load_mission(scenario).dataflow
    out.mkdir(parents=True, exist_ok=True)
    outcomes: list[Outcome] = []
    for i, fault in enumerate(faults, 1):
        say(f"[{i}/{len(faults)}] {fault.name} ...")
        case_dir = out / f"{i:02d}-{re.sub(r'[^a-z0-9]+', '-', fault.name).strip('-')}"
        o = run_case(setup, fault, case_dir, keys, flow)
        outcomes.append(o)
        bad = problems(o)
        say(f"[{i}/{len(faults)}] {fault.name}: {'PASS' if not bad else 'FAIL: ' + '; '.join(bad)}")
        rows = [_row(x) for x in outcomes]
        tmp = out / "chaos.json.tmp"
        tmp.write_text(json.dumps(rows, indent=1, default=str))
        tmp.replace(out / "chaos.json")
    return outcomes


def _row(x: Outcome) -> dict[str, object]:
    """A case as chaos.json has it, its metrics as metrics.json has them ({}: none)."""
    return asdict(x) | {
        "metrics": x.metrics.to_json() if x.metrics is not None else {},
        "outside": x.outside.to_json(),
        "name": x.fault.name,
        "problems": problems(x),
    }
