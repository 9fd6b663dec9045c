"""`tidelink reproduce`: the paper's section-4 comparison on a perfect and a lossy network."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from common.config.network import NetworkConfig
from common.config.scenario import load_scenario
from common.config.world import WorldConfig
from services.experiments import figures
from services.experiments.report import ReportInputs, write_report
from services.experiments.results import as_number
from services.experiments.schema import Axis, AxisValue, Experiment, SetValue
from services.experiments.summary import aggregate
from services.experiments.sweep import SweepOptions, SweepReport, run_sweep
from services.experiments.tuning import (
    CONTROLLERS,
    PERFECT_NETWORK,
    Candidate,
    choose,
    chosen_set,
    save_choice,
    score,
    tuning_experiment,
)

NETWORKS = ("perfect", "lossy")
# The paper's three controllers each follow the one shortest path: keep the first plan for the
# whole run (no replan is ever due), unless --replan lets the planner react as in a mission.
FIXED_PATH: dict[str, SetValue] = {"planner.min_replan_interval_s": 1e9}


def planning_overrides(replan: bool) -> dict[str, SetValue]:
    return {} if replan else dict(FIXED_PATH)


def describe_network(cfg: NetworkConfig) -> str:
    """One line about a scenario's default link profile, for the report."""
    d = cfg.default
    parts = [f"{1000 * d.delay_s:.0f} ms one-way delay"]
    if d.jitter != "none":
        parts.append(f"{d.jitter} jitter {1000 * d.jitter_s:.0f} ms")
    if d.loss == "bernoulli":
        parts.append(f"{100 * d.loss_p:.0f} % Bernoulli loss")
    elif d.loss == "gilbert_elliott":
        parts.append(f"Gilbert-Elliott loss (p_gb {d.ge_p_gb}, p_bg {d.ge_p_bg})")
    extra = f", {len(cfg.links)} per-link overrides" if cfg.links else ""
    extra += f", {len(cfg.outages)} outages" if cfg.outages else ""
    return "the scenario's own network: " + ", ".join(parts) + extra


@dataclass(frozen=True, kw_only=True)
class ReproduceOptions:
    """What `tidelink reproduce` runs and where."""

    out: Path
    scenario: Path = Path("configs/default.toml")
    seeds: int = 3
    first_seed: int = 1
    runtime: str = "lockstep"
    jobs: int = 1
    scheduler: str = ""
    tune: bool = False
    tune_seeds: int = 2
    tune_first_seed: int = 101  # disjoint from the evaluation seeds
    tune_factors: tuple[float, ...] = (0.5, 1.0, 2.0)
    replan: bool = False  # False: every controller follows the first plan (the paper's setup)
    rich: bool | None = None
    command: str = ""


@dataclass(frozen=True, kw_only=True)
class ReproduceResult:
    report: Path
    sweep: SweepReport
    tuned: dict[str, Candidate] | None


def _tune(opts: ReproduceOptions) -> tuple[dict[str, Candidate], list[Candidate]]:
    scenario, _ = load_scenario(opts.scenario)
    exp = tuning_experiment(
        str(opts.scenario.resolve()),
        scenario,
        seeds=opts.tune_seeds,
        first_seed=opts.tune_first_seed,
        factors=opts.tune_factors,
        extra=planning_overrides(opts.replan),
    )
    rep = run_sweep(
        exp,
        "tidelink reproduce --tune",
        SweepOptions(
            out=opts.out / "tuning",
            runtime=opts.runtime,
            jobs=opts.jobs,
            scheduler=opts.scheduler,
            rich=opts.rich,
        ),
    )
    candidates = score(rep.rows, exp)
    best = choose(candidates)
    save_choice(
        opts.out / "tuning" / "chosen.json",
        best,
        opts.tune_factors,
        list(range(opts.tune_first_seed, opts.tune_first_seed + opts.tune_seeds)),
    )
    return best, candidates


def comparison_experiment(opts: ReproduceOptions, gains: dict[str, SetValue]) -> Experiment:
    """Network (perfect, lossy) x the three controllers x seeds, with the chosen gains."""
    nets = (AxisValue(label="perfect", set=dict(PERFECT_NETWORK)), AxisValue(label="lossy"))
    return Experiment(
        name="reproduce",
        scenario=str(opts.scenario.resolve()),
        seeds=opts.seeds,
        first_seed=opts.first_seed,
        controllers=CONTROLLERS,
        set={**gains, **planning_overrides(opts.replan)},
        axes=(Axis(name="network", values=nets, x_label="network"),),
    )


def reproduce(opts: ReproduceOptions) -> ReproduceResult:
    """Optionally tune, run the comparison, draw the figures and write DIR/REPORT.md."""
    tuned, candidates = (None, []) if not opts.tune else _tune(opts)
    exp = comparison_experiment(opts, chosen_set(tuned) if tuned else {})
    sweep = run_sweep(
        exp,
        "tidelink reproduce",
        SweepOptions(
            out=opts.out,
            runtime=opts.runtime,
            jobs=opts.jobs,
            scheduler=opts.scheduler,
            keep_trajectories=True,
            rich=opts.rich,
        ),
    )
    grid = tuple(a.name for a in exp.all_axes)
    cells = aggregate(sweep.rows, grid)
    scenario, _ = load_scenario(opts.scenario)
    figs = _figures(opts, sweep, scenario.world)
    from services.mission.metrics import ON_PATH_TOL_M  # the tolerance the metric uses

    inp = ReportInputs(
        scenario=str(opts.scenario),
        runtime=opts.runtime,
        area=_area(scenario.world),
        networks={
            "perfect": "no delay, no loss (the paper's setting)",
            "lossy": describe_network(scenario.network),
        },
        seeds=list(range(opts.first_seed, opts.first_seed + opts.seeds)),
        on_path_tol_m=ON_PATH_TOL_M,
        cells=cells,
        figures=figs,
        errors=sweep.errors,
        tuned=tuned,
        candidates=candidates,
        tune_seeds=list(range(opts.tune_first_seed, opts.tune_first_seed + opts.tune_seeds)),
        same_first_plan=_same_first_plan(sweep.rows),
        replan=opts.replan,
        corridor_m=scenario.planner.corridor_halfwidth_m,
        left_corridor=_left_corridor(sweep.rows, scenario.planner.corridor_halfwidth_m),
        command=opts.command,
    )
    path = opts.out / "REPORT.md"
    write_report(path, inp)
    return ReproduceResult(report=path, sweep=sweep, tuned=tuned)


def _area(w: WorldConfig) -> str:
    a = w.area
    return f"{a.x_max_m - a.x_min_m:g} m x {a.y_max_m - a.y_min_m:g} m"


def _same_first_plan(rows: list[dict[str, str]]) -> dict[str, bool]:
    """Per network: did every controller start from the same first plan in each seed?"""
    out: dict[str, bool] = {}
    for net in NETWORKS:
        by_seed: dict[str, set[str]] = {}
        for r in rows:
            if r.get("network") == net and r.get("status") == "ok":
                by_seed.setdefault(r["seed"], set()).add(r.get("planned_length_m", ""))
        out[net] = bool(by_seed) and all(len(v) == 1 for v in by_seed.values())
    return out


def _left_corridor(
    rows: list[dict[str, str]], corridor_m: float
) -> dict[tuple[str, str], tuple[int, int]]:
    """Per (network, controller): runs whose max XTE to the optimal path left its corridor."""
    out: dict[tuple[str, str], tuple[int, int]] = {}
    for r in rows:
        if r.get("status") != "ok":
            continue
        key = (r["network"], r["controller"])
        k, n = out.get(key, (0, 0))
        out[key] = (k + (as_number(r.get("xte_optimal_max_m")) > corridor_m), n + 1)
    return out


def _figures(
    opts: ReproduceOptions, sweep: SweepReport, world: WorldConfig
) -> dict[str, list[str]]:
    """Figures 2-6 for each network from the first seed's trajectories."""
    fig_dir = opts.out / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    out: dict[str, list[str]] = {}
    for net in NETWORKS:
        trajs = {}
        for r in sweep.rows:
            if (
                r.get("network") == net
                and r.get("seed") == str(opts.first_seed)
                and r.get("status") == "ok"
            ):
                f = opts.out / "runs" / r["run_id"] / "trajectory.npz"
                if f.exists():
                    trajs[r["controller"]] = figures.load_trajectory(f)
        names = []
        for i, ctrl in enumerate(c for c in CONTROLLERS if c in trajs):
            name = f"figures/{net}_{i + 2}_{ctrl}.png"
            figures.trajectory_figure(
                opts.out / name,
                world,
                ctrl,
                trajs[ctrl],
                f"{figures.NAMES[ctrl]}, {net} network, seed {opts.first_seed}",
            )
            names.append(name)
        if trajs:
            figures.overlay_figure(
                opts.out / f"figures/{net}_5_overlay.png",
                world,
                trajs,
                f"The three controllers, {net} network",
            )
            figures.time_distance_figure(
                opts.out / f"figures/{net}_6_time_distance.png",
                trajs,
                f"Time against distance travelled, {net} network",
            )
            names += [f"figures/{net}_5_overlay.png", f"figures/{net}_6_time_distance.png"]
        out[net] = names
    return out
