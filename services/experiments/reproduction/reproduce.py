"""`tidelink reproduce`: the paper's section-4 comparison on a perfect and a lossy network."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from common.config.network import NetworkConfig
from common.config.scenario import load_scenario
from common.config.world import WorldConfig
from services.experiments.reproduction import figures
from services.experiments.reproduction.cases import CASES
from services.experiments.reproduction.report import ReportInputs, write_report
from services.experiments.reproduction.tuning import (
    CONTROLLERS,
    Box,
    Candidate,
    Tuning,
    choose,
    chosen_set,
    save_choice,
    score,
    tuning_experiment,
)
from services.experiments.sweep.results import as_number
from services.experiments.sweep.run import SweepOptions, SweepReport, run_sweep
from services.experiments.sweep.schema import Axis, AxisValue, Experiment, SetValue
from services.experiments.sweep.summary import aggregate

# The paper's three controllers each follow the one shortest path: keep the first plan for the
# whole run (no replan is ever due), unless --replan lets the planner react as in a mission.
FIXED_PATH: dict[str, SetValue] = {"planner.min_replan_interval_s": 1e9}
# The paper's pipeline as published: eq. (2) mean filter and eq. (3) lag on the fixes.
PAPER_PIPELINE: dict[str, SetValue] = {"estimator.prefilter": "mean+lag"}
# The moving obstacles of the default field pass the planned path by chance; this scenario
# sends them across it (eqs. (12)-(13) and replanning are what carry the vehicle through).
CROSSING = Path("configs/experiments/scenarios/crossing.toml")


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

    out: Path  # the runs (results.csv, logs, trajectories)
    report_dir: Path | None = None  # REPORT.md and figures/ (default: out)
    scenario: Path = Path("configs/default.toml")
    crossing: Path | None = CROSSING  # None: no crossing-obstacles section
    seeds: int = 5
    first_seed: int = 1
    runtime: str = "inproc"
    jobs: int = 1
    scheduler: str = ""
    tune: bool = True
    tune_seeds: int = 2
    tune_first_seed: int = 101  # disjoint from the evaluation seeds
    tune_box: Box = Box()  # the first box of the search (exponents of tune_step)
    tune_step: float = 2.0
    tune_limit: int = 6  # a box never goes beyond factors tune_step**-6 .. tune_step**6
    replan: bool = False  # False: every controller follows the first plan (the paper's setup)
    rich: bool | None = None
    command: str = ""

    @property
    def report_root(self) -> Path:
        return self.out if self.report_dir is None else self.report_dir


@dataclass(frozen=True, kw_only=True)
class ReproduceResult:
    report: Path
    sweep: SweepReport
    crossing: SweepReport | None
    tuning: Tuning | None


def _sweep(
    opts: ReproduceOptions, exp: Experiment, out: Path, keep: bool = False, plots: bool = True
) -> SweepReport:
    return run_sweep(
        exp,
        f"tidelink reproduce ({exp.name})",
        SweepOptions(
            out=out,
            runtime=opts.runtime,
            jobs=opts.jobs,
            scheduler=opts.scheduler,
            keep_trajectories=keep,
            rich=opts.rich,
            plots=plots,
        ),
    )


def _base_overrides(opts: ReproduceOptions) -> dict[str, SetValue]:
    """What every comparison and tuning run shares: the paper's pipeline and planning mode."""
    return {**PAPER_PIPELINE, **planning_overrides(opts.replan)}


def tune(opts: ReproduceOptions) -> Tuning:
    """The gain search (tuning.py), the same procedure for each controller: run its box,
    widen it while its choice lies on the edge. Each round runs only the points not yet run
    (the sweep resumes in DIR/tuning/<controller>)."""
    scenario, _ = load_scenario(opts.scenario)
    best: dict[str, Candidate] = {}
    candidates: list[Candidate] = []
    boxes: dict[str, Box] = {}
    rounds: dict[str, int] = {}
    for ctrl in CONTROLLERS:
        box, n = opts.tune_box, 0
        while True:
            n += 1
            exp = tuning_experiment(
                str(opts.scenario.resolve()),
                scenario,
                ctrl,
                box=box,
                step=opts.tune_step,
                seeds=opts.tune_seeds,
                first_seed=opts.tune_first_seed,
                extra=_base_overrides(opts),
            )
            # the gain tables are the tuning's product (chosen.json, the report): no plots
            rep = _sweep(opts, exp, opts.out / "tuning" / ctrl, plots=False)
            scored = score(rep.rows, exp, ctrl, box, opts.tune_step)
            choice = choose(scored)
            wider = box.widened(choice, opts.tune_limit)
            if wider is None:
                break
            print(
                f"reproduce: {ctrl}'s choice lies on the edge of its gain grid: widening to {wider}"
            )
            box = wider
        best |= choice
        candidates += scored
        boxes[ctrl], rounds[ctrl] = box, n
    seeds = list(range(opts.tune_first_seed, opts.tune_first_seed + opts.tune_seeds))
    save_choice(opts.out / "tuning" / "chosen.json", best, boxes, opts.tune_step, seeds)
    return Tuning(best=best, candidates=candidates, boxes=boxes, rounds=rounds)


def comparison_experiment(opts: ReproduceOptions, gains: dict[str, SetValue]) -> Experiment:
    """The cases (network x compensation for all, and the eq. (2)-(3) ablation) x the three
    controllers x seeds, with the chosen gains."""
    cases = tuple(AxisValue(label=c.label, set=c.overrides()) for c in CASES)
    return Experiment(
        name="reproduce",
        scenario=str(opts.scenario.resolve()),
        seeds=opts.seeds,
        first_seed=opts.first_seed,
        controllers=CONTROLLERS,
        set={**gains, **_base_overrides(opts)},
        axes=(Axis(name="case", values=cases, x_label="case"),),
    )


def crossing_experiment(
    opts: ReproduceOptions, path: Path, gains: dict[str, SetValue]
) -> Experiment:
    """Moving obstacles across the planned path: the planner replans (that is the point),
    compensation on for all, the three controllers x seeds."""
    return Experiment(
        name="crossing",
        scenario=str(path.resolve()),
        seeds=opts.seeds,
        first_seed=opts.first_seed,
        controllers=CONTROLLERS,
        set={**gains, **PAPER_PIPELINE, "controller.delay_compensation": True},
        axes=(Axis(name="case", values=(AxisValue(label="crossing"),), x_label="case"),),
    )


def reproduce(opts: ReproduceOptions) -> ReproduceResult:
    """Tune (unless told not to), run the comparison and the crossing scenario, draw the
    figures and write REPORT.md."""
    tuning = tune(opts) if opts.tune else None
    gains = chosen_set(tuning.best) if tuning else {}
    exp = comparison_experiment(opts, gains)
    sweep = _sweep(opts, exp, opts.out, keep=True)
    crossing = None
    if opts.crossing is not None:
        crossing = _sweep(
            opts, crossing_experiment(opts, opts.crossing, gains), opts.out / "crossing", keep=True
        )
    rows = sweep.rows + (crossing.rows if crossing else [])
    cells = aggregate(rows, ("case", "controller"))
    scenario, _ = load_scenario(opts.scenario)
    root = opts.report_root
    figs = _figures(opts, root, sweep, scenario.world, ("perfect", "lossy"))
    if crossing is not None and opts.crossing is not None:
        cross_world = load_scenario(opts.crossing)[0].world
        figs |= _figures(opts, root, crossing, cross_world, ("crossing",), "crossing")
    from services.mission.metrics import ON_PATH_TOL_M  # the tolerance the metric uses

    inp = ReportInputs(
        scenario=str(opts.scenario),
        crossing=str(opts.crossing) if crossing is not None else "",
        runtime=opts.runtime,
        area=_area(scenario.world),
        networks={
            "perfect": "no delay, no loss (the paper's setting)",
            "lossy": describe_network(scenario.network),
        },
        cases=CASES,
        seeds=list(range(opts.first_seed, opts.first_seed + opts.seeds)),
        on_path_tol_m=ON_PATH_TOL_M,
        r_min_m=scenario.vehicle.turn_radius_min_m,
        rho0_m=scenario.planner.rho0_m,
        cells=cells,
        figures=figs,
        errors=sweep.errors + (crossing.errors if crossing else 0),
        tuning=tuning,
        tune_step=opts.tune_step,
        tune_limit=opts.tune_limit,
        tune_seeds=list(range(opts.tune_first_seed, opts.tune_first_seed + opts.tune_seeds)),
        same_first_plan=_same_first_plan(sweep.rows),
        replan=opts.replan,
        corridor_m=scenario.planner.corridor_halfwidth_m,
        left_corridor=_left_corridor(sweep.rows, scenario.planner.corridor_halfwidth_m),
        command=opts.command,
    )
    root.mkdir(parents=True, exist_ok=True)
    path = root / "REPORT.md"
    write_report(path, inp)
    return ReproduceResult(report=path, sweep=sweep, crossing=crossing, tuning=tuning)


def _area(w: WorldConfig) -> str:
    a = w.area
    return f"{a.x_max_m - a.x_min_m:g} m x {a.y_max_m - a.y_min_m:g} m"


def _same_first_plan(rows: list[dict[str, str]]) -> dict[str, bool]:
    """Per case: did every controller start from the same first plan in each seed?"""
    out: dict[str, bool] = {}
    for case in CASES:
        by_seed: dict[str, set[str]] = {}
        for r in rows:
            if r.get("case") == case.label and r.get("status") == "ok":
                by_seed.setdefault(r["seed"], set()).add(r.get("planned_length_m", ""))
        out[case.label] = bool(by_seed) and all(len(v) == 1 for v in by_seed.values())
    return out


def _left_corridor(
    rows: list[dict[str, str]], corridor_m: float
) -> dict[tuple[str, str], tuple[int, int]]:
    """Per (case, controller): runs whose max XTE to the optimal path left its corridor."""
    out: dict[tuple[str, str], tuple[int, int]] = {}
    for r in rows:
        if r.get("status") != "ok":
            continue
        key = (r["case"], r["controller"])
        k, n = out.get(key, (0, 0))
        out[key] = (k + (as_number(r.get("xte_optimal_max_m")) > corridor_m), n + 1)
    return out


def _figures(
    opts: ReproduceOptions,
    root: Path,
    sweep: SweepReport,
    world: WorldConfig,
    cases: tuple[str, ...],
    runs: str = "",
) -> dict[str, list[str]]:
    """Figures 2-6 for each case from the first seed's trajectories (REPORT_DIR/figures)."""
    fig_dir = root / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    out: dict[str, list[str]] = {}
    for case in cases:
        trajs = {}
        for r in sweep.rows:
            if (
                r.get("case") == case
                and r.get("seed") == str(opts.first_seed)
                and r.get("status") == "ok"
            ):
                f = opts.out / runs / "runs" / r["run_id"] / "trajectory.npz"
                if f.exists():
                    trajs[r["controller"]] = figures.load_trajectory(f)
        names = []
        for i, ctrl in enumerate(c for c in CONTROLLERS if c in trajs):
            name = f"figures/{case}_{i + 2}_{ctrl}.png"
            figures.trajectory_figure(
                root / name,
                world,
                ctrl,
                trajs[ctrl],
                f"{figures.NAMES[ctrl]}, {case}, seed {opts.first_seed}",
            )
            names.append(name)
        if trajs:
            figures.overlay_figure(
                root / f"figures/{case}_5_overlay.png",
                world,
                trajs,
                f"The three controllers, {case}",
            )
            figures.time_distance_figure(
                root / f"figures/{case}_6_time_distance.png",
                trajs,
                f"Time against distance travelled, {case}",
            )
            names += [f"figures/{case}_5_overlay.png", f"figures/{case}_6_time_distance.png"]
        out[case] = names
    return out
