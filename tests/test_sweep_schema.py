"""Experiment files: the shipped grids, run ids, and errors that name the file and the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.config.loader import ConfigError
from common.config.scenario import scenario_from_raw
from services.experiments.sweep.grid import expand
from services.experiments.sweep.run import SweepOptions, run_sweep
from services.experiments.sweep.schema import load_experiment

ROOT = Path(__file__).resolve().parents[1]
EXP = ROOT / "configs" / "experiments"
SMALL = EXP / "scenarios" / "small.toml"


def _plan(name: str, runtime: str = "inproc") -> list:
    exp = load_experiment(EXP / name)
    return list(expand(exp, name, runtime=runtime).runs)


@pytest.mark.parametrize(
    ("name", "n_runs"),
    [
        ("delay.toml", 54),
        ("loss.toml", 54),
        ("burst.toml", 45),
        ("outage.toml", 45),
        ("smoke.toml", 27),
    ],
)
def test_shipped_experiments_expand_into_valid_scenarios(name: str, n_runs: int) -> None:
    runs = _plan(name)
    assert len(runs) == n_runs
    assert len({r.run_id for r in runs}) == n_runs  # every run id unique
    assert {r.labels["controller"] for r in runs} == {"nurbs", "backstepping", "fuzzy_pid"}
    for r in runs:
        s = scenario_from_raw(r.raw)
        assert s.run.seed == r.seed and s.runtime.kind == "inproc"
        assert s.controller.kind == r.labels["controller"]
        assert s.run.name.endswith(r.run_id)  # distinct names keep parallel lockstep runs apart


def test_delay_and_loss_sweeps_span_the_issue_ranges() -> None:
    delays = {scenario_from_raw(r.raw).network.default.delay_s for r in _plan("delay.toml")}
    assert min(delays) == 0.0 and max(delays) == 1.0 and len(delays) == 6
    loss = {scenario_from_raw(r.raw).network.default.loss_p for r in _plan("loss.toml")}
    assert min(loss) == 0.0 and max(loss) == 0.5 and len(loss) == 6


def test_burst_sweep_holds_the_mean_loss_while_bursts_grow() -> None:
    bursts = []
    for r in _plan("burst.toml"):
        d = scenario_from_raw(r.raw).network.default
        assert d.loss == "gilbert_elliott" and d.ge_loss_good == 0.0 and d.ge_loss_bad == 1.0
        assert d.ge_p_gb / (d.ge_p_gb + d.ge_p_bg) == pytest.approx(0.10, abs=1e-5)
        bursts.append(1.0 / d.ge_p_bg)
    assert min(bursts) == pytest.approx(1.0 / 0.9) and max(bursts) == pytest.approx(20.0)


def test_outage_sweep_takes_the_planner_down_for_growing_windows() -> None:
    lengths = set()
    for r in _plan("outage.toml"):
        outs = scenario_from_raw(r.raw).network.outages
        lengths.add(sum(o.end_s - o.start_s for o in outs))
        assert all(o.service == "planner" and o.start_s == 15.0 for o in outs)
    assert lengths == {0.0, 1.0, 2.0, 5.0, 10.0}


def test_the_current_sweep_turns_the_water_round_the_compass_at_two_speeds() -> None:
    runs = _plan("current.toml")
    assert len(runs) == 16 and len({r.run_id for r in runs}) == 16
    cells = set()
    for r in runs:
        c = scenario_from_raw(r.raw).world.current
        assert c.direction == "fixed" and (c.shear_mps, c.sigma_mps, c.eddies) == (0.0, 0.0, ())
        cells.add((c.speed_mps, c.direction_deg))
    assert cells == {(v, d) for v in (0.1, 0.3) for d in (0.0, 90.0, 180.0, 270.0)}
    assert {r.seed for r in runs} == {1, 2} and {r.labels["controller"] for r in runs} == {"nurbs"}


def test_run_ids_are_stable_and_depend_on_cell_and_seed() -> None:
    a, b = _plan("smoke.toml"), _plan("smoke.toml", runtime="lockstep")
    assert [r.run_id for r in a] == [r.run_id for r in b]  # the runtime is not part of a run
    seeds_of_one_cell = [r for r in a if r.labels == a[0].labels]
    assert [r.seed for r in seeds_of_one_cell] == [1, 2, 3]


def _write(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "exp.toml"
    p.write_text(f'name = "t"\nscenario = "{SMALL}"\n' + body)
    return p


def test_an_unknown_key_names_the_file_and_key(tmp_path: Path) -> None:
    p = _write(tmp_path, "seedz = 3\n")
    with pytest.raises(ConfigError, match=r"exp\.toml: seedz: unknown key"):
        load_experiment(p)
    p = _write(tmp_path, '[[axes]]\nname = "a"\n[[axes.values]]\nlabel = "x"\nsett = {}\n')
    with pytest.raises(ConfigError, match=r"exp\.toml: axes\[0\]\.values\[0\]\.sett: unknown"):
        load_experiment(p)


def test_a_bad_cell_names_the_axis_value_and_scenario_key(tmp_path: Path) -> None:
    p = _write(
        tmp_path,
        '[[axes]]\nname = "delay"\n'
        '[[axes.values]]\nlabel = "ok"\nset = { "network.default.delay_s" = 0.1 }\n'
        '[[axes.values]]\nlabel = "bad"\n'
        'set = { "network.default.delay_s" = -1.0 }\n',
    )
    exp = load_experiment(p)
    with pytest.raises(ConfigError) as err:
        expand(exp, str(p), runtime="inproc")
    msg = str(err.value)
    assert msg.startswith(f"{p}: axes[0].values[1].set.network.default.delay_s:")
    assert "delay=bad" in msg and "expected a finite value >= 0" in msg


def test_nothing_runs_when_one_cell_is_invalid(tmp_path: Path) -> None:
    p = _write(
        tmp_path,
        'controllers = ["nurbs"]\n[[axes]]\nname = "v"\n'
        '[[axes.values]]\nlabel = "ok"\n'
        '[[axes.values]]\nlabel = "bad"\nset = { "vehicle.v_max_mps" = "fast" }\n',
    )
    out = tmp_path / "out"
    with pytest.raises(ConfigError, match=r"axes\[0\]\.values\[1\]\.set\.vehicle\.v_max_mps"):
        run_sweep(load_experiment(p), str(p), SweepOptions(out=out, runtime="inproc"))
    assert not (out / "results.csv").exists()


def test_two_axes_may_not_set_the_same_key(tmp_path: Path) -> None:
    p = _write(
        tmp_path,
        '[[axes]]\nname = "a"\n[[axes.values]]\nlabel = "x"\n'
        'set = { "network.default" = {} }\n'
        '[[axes]]\nname = "b"\n[[axes.values]]\nlabel = "y"\n'
        'set = { "network.default.delay_s" = 0.1 }\n',
    )
    with pytest.raises(ConfigError, match=r"exp\.toml: axes: axes 'a' and 'b' both set"):
        load_experiment(p)


def test_tables_and_arrays_of_tables_are_valid_override_values(tmp_path: Path) -> None:
    p = _write(
        tmp_path,
        '[[axes]]\nname = "net"\n[[axes.values]]\nlabel = "x"\nset = { '
        '"network.links" = [{ link = "planner/cmd->vehicle", '
        'profile = { delay_s = 0.3, loss = "bernoulli", loss_p = 0.1 } }], '
        '"network.outages" = [{ start_s = 1.0, end_s = 2.0, service = "sensor" }]'
        " }\n",
    )
    (run,) = expand(load_experiment(p), str(p), runtime="inproc").runs[:1]
    net = scenario_from_raw(run.raw).network
    assert net.links[0].link == "planner/cmd->vehicle" and net.links[0].profile.loss_p == 0.1
    assert net.outages[0].service == "sensor" and net.outages[0].end_s == 2.0


def test_the_documented_example_is_a_valid_experiment(tmp_path: Path) -> None:
    guide = (ROOT / "docs" / "experiments.md").read_text()
    section = guide[guide.index("## `tidelink sweep`") :]
    example = section[
        section.index("```toml\n") + 8 : section.index("```\n", section.index("```toml\n") + 8)
    ]
    (tmp_path / "exp").mkdir()
    p = tmp_path / "exp" / "delay.toml"
    p.write_text(example.replace('"../default.toml"', f'"{ROOT / "configs" / "default.toml"}"'))
    runs = expand(load_experiment(p), str(p), runtime="inproc").runs
    assert len(runs) == 2 * 3 * 3  # 2 values x 3 controllers x 3 seeds
    link = scenario_from_raw(runs[-1].raw).network.links
    assert [o.link for o in link] == ["planner/cmd->vehicle"]


def test_the_prepared_tails_sweep_pairs_every_fault_with_and_without_them() -> None:
    runs = _plan("networked/prepared.toml")
    assert len(runs) == 5 * 2 * 3 * 20 and len({r.run_id for r in runs}) == len(runs)
    fresh: dict[str, set[float]] = {}
    for r in runs:
        s = scenario_from_raw(r.raw)
        fresh.setdefault(r.labels["tail"], set()).add(s.controller.sequence.fresh_s)
        assert s.controller.sequence.horizon_s == 10.0  # sequences on in every cell
    # prepared: the default; all-fresh: as long as the horizon, every entry in the step
    assert fresh == {"prepared": {0.5}, "all-fresh": {10.0}}
    faults = {r.labels["fault"] for r in runs}
    assert faults == {"loss50pct", "burst20", "outage10s", "outage20s", "delay1s"}
