"""The world's ocean current: values by hand, non-divergence, seeds, gust statistics, order."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from common.config.current import CurrentConfig, EddyConfig
from common.config.loader import ConfigError
from common.config.scenario import load_scenario
from common.config.vehicle import VehicleConfig
from common.config.world import AreaConfig
from common.messages import VelocityCommand
from common.runtime.model.core import Delivery
from common.world.current import CurrentField, seeded_direction_deg
from services.cli import main
from services.mission.dataflow import current_field
from services.vehicle.core import VehicleCore

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
AREA = AreaConfig()  # 100 m x 40 m, centre (50, 20)
EDDY = EddyConfig(x_m=50.0, y_m=20.0, radius_m=5.0, speed_mps=0.4)
STORMY = CurrentConfig(
    speed_mps=0.3,
    direction_deg=25.0,
    shear_mps=-0.1,
    eddies=(EDDY, EddyConfig(x_m=20.0, y_m=10.0, radius_m=8.0, speed_mps=-0.25)),
    tidal_period_s=600.0,
    tidal_amplitude=0.4,
    tidal_phase_rad=0.3,
    sigma_mps=0.05,
    tau_s=20.0,
)


def _field(seed: int = 1, **kw: Any) -> CurrentField:
    return CurrentField(CurrentConfig(**kw), AREA, seed)


def test_the_calm_default_is_exactly_zero_and_free() -> None:
    f = _field()
    assert f.is_calm and f.speed_bound_mps() == 0.0
    for x, y, t in ((0.0, 0.0, 0.0), (37.2, -5.0, 123.4), (1e4, 1e4, -3.0)):
        assert f.velocity(x, y, t) == (0.0, 0.0)
    # an eddy of no strength is no current either
    assert _field(eddies=(EddyConfig(x_m=1.0, y_m=1.0, radius_m=1.0, speed_mps=0.0),)).is_calm


def test_uniform_flow_goes_towards_its_direction() -> None:
    north = _field(speed_mps=0.3, direction_deg=90.0)
    assert not north.is_calm and north.speed_bound_mps() == 0.3
    assert north.velocity(3.0, 4.0, 5.0) == (0.0, 0.3)  # exact on the compass points
    assert _field(speed_mps=0.2, direction_deg=-180.0).velocity(0.0, 0.0, 0.0) == (-0.2, 0.0)
    cx, cy = _field(speed_mps=0.3, direction_deg=30.0).velocity(80.0, 1.0, 0.0)
    assert cx == pytest.approx(0.3 * math.sqrt(3) / 2, abs=1e-15)
    assert cy == pytest.approx(0.15, abs=1e-15)


def test_shear_varies_the_speed_linearly_across_the_flow() -> None:
    # eastward flow: the left edge (looking downstream) is the north edge y = 40, W = 20 m
    east = _field(speed_mps=0.5, shear_mps=0.2)
    for y, u in ((40.0, 0.6), (30.0, 0.55), (20.0, 0.5), (0.0, 0.4), (55.0, 0.6), (-9.0, 0.4)):
        cx, cy = east.velocity(12.3, y, 7.0)
        assert cx == pytest.approx(u, abs=1e-15) and cy == 0.0
    assert east.speed_bound_mps() == pytest.approx(0.6)
    # northward flow: the left edge is the west edge x = 0, W = 50 m; a negative shear
    north = _field(speed_mps=0.5, shear_mps=-0.2, direction_deg=90.0)
    for x, v in ((0.0, 0.4), (25.0, 0.45), (50.0, 0.5), (100.0, 0.6)):
        assert north.velocity(x, 3.0, 0.0) == pytest.approx((0.0, v), abs=1e-15)


def test_the_tide_scales_the_flow() -> None:
    f = _field(speed_mps=0.2, shear_mps=0.1, tidal_period_s=400.0, tidal_amplitude=0.5)
    assert f.velocity(50.0, 40.0, 0.0) == pytest.approx((0.25, 0.0))  # sin 0: factor 1
    assert f.velocity(50.0, 40.0, 100.0) == pytest.approx((0.375, 0.0))  # quarter: 1 + A
    assert f.velocity(50.0, 40.0, 300.0) == pytest.approx((0.125, 0.0))  # 1 - A
    assert f.speed_bound_mps() == pytest.approx(0.375)
    reversing = _field(speed_mps=0.2, tidal_period_s=400.0, tidal_amplitude=2.0)
    assert reversing.velocity(0.0, 0.0, 300.0)[0] == pytest.approx(-0.2)  # the ebb


def test_a_gaussian_eddy_by_hand() -> None:
    f = CurrentField(CurrentConfig(eddies=(EDDY,)), AREA, 1)
    assert f.velocity(50.0, 20.0, 0.0) == (0.0, 0.0)  # still at the centre
    # counter-clockwise, peak V = 0.4 m/s at r = R = 5 m
    assert f.velocity(55.0, 20.0, 0.0) == pytest.approx((0.0, 0.4), abs=1e-15)
    assert f.velocity(50.0, 25.0, 0.0) == pytest.approx((-0.4, 0.0), abs=1e-15)
    # V (r/R) exp((1 - r^2/R^2) / 2) at r = 2R, to the west: pointing south
    assert f.velocity(40.0, 20.0, 9.0) == pytest.approx(
        (0.0, -0.4 * 2.0 * math.exp(-1.5)), abs=1e-15
    )
    clockwise = CurrentField(
        CurrentConfig(eddies=(EddyConfig(x_m=50.0, y_m=20.0, radius_m=5.0, speed_mps=-0.4),)),
        AREA,
        1,
    )
    assert clockwise.velocity(55.0, 20.0, 0.0) == pytest.approx((0.0, -0.4), abs=1e-15)
    # the peak is the fastest anywhere: sampled on rings the speed never exceeds V
    r = np.linspace(0.0, 30.0, 601)
    u, v = f.sample(0.0, 50.0 + r, np.full_like(r, 20.0))
    assert np.max(np.hypot(u, v)) == pytest.approx(0.4, abs=1e-12)
    assert r[np.argmax(np.hypot(u, v))] == 5.0


def test_the_field_is_non_divergent() -> None:
    # central differences of u_x + v_y at random points, with eddies and shear: ~0, while the
    # vorticity v_x - u_y of the same differences is far from it (the test can see structure)
    f = CurrentField(
        CurrentConfig(speed_mps=0.3, direction_deg=40.0, shear_mps=0.3, eddies=STORMY.eddies),
        AREA,
        1,
    )
    rng = np.random.default_rng(4)
    h = 1e-4
    worst_div, best_curl = 0.0, 0.0
    for x, y in rng.uniform((10.0, 5.0), (90.0, 35.0), (200, 2)):
        ux = (f.velocity(x + h, y, 0.0)[0] - f.velocity(x - h, y, 0.0)[0]) / (2 * h)
        vy = (f.velocity(x, y + h, 0.0)[1] - f.velocity(x, y - h, 0.0)[1]) / (2 * h)
        vx = (f.velocity(x + h, y, 0.0)[1] - f.velocity(x - h, y, 0.0)[1]) / (2 * h)
        uy = (f.velocity(x, y + h, 0.0)[0] - f.velocity(x, y - h, 0.0)[0]) / (2 * h)
        worst_div = max(worst_div, abs(ux + vy))
        best_curl = max(best_curl, abs(vx - uy))
    assert worst_div < 1e-9
    assert best_curl > 0.05


def test_a_seeded_direction_is_one_per_seed() -> None:
    kw = {"speed_mps": 0.2, "direction": "seeded", "direction_deg": 123.0}
    dirs = [_field(seed, **kw).direction_deg for seed in range(1, 41)]
    assert len(set(dirs)) == 40 and all(0.0 <= d < 360.0 for d in dirs)
    assert 123.0 not in dirs  # direction_deg is ignored
    assert max(dirs) - min(dirs) > 270.0  # spread over the compass
    a, b = _field(7, **kw), _field(7, **kw)
    assert a.direction_deg == b.direction_deg == seeded_direction_deg(7)
    assert a.velocity(3.0, 4.0, 5.0) == b.velocity(3.0, 4.0, 5.0)
    c = math.radians(a.direction_deg)
    assert a.velocity(0.0, 0.0, 0.0) == pytest.approx((0.2 * math.cos(c), 0.2 * math.sin(c)))


def test_gusts_have_the_stationary_std_and_correlation() -> None:
    # sigma = 0.05 m/s, tau = 5 s, knots every 1 s: over 20000 knots the std is within 5 %,
    # the lag-1 correlation exp(-1/5) within 0.03 (sampling error ~0.01 at this length),
    # the axes uncorrelated
    f = _field(11, sigma_mps=0.05, tau_s=5.0, update_s=1.0)
    b = np.array([f.gust(float(j)) for j in range(20000)])
    for axis in (0, 1):
        assert abs(b[:, axis].std() - 0.05) < 0.05 * 0.05
        r1 = np.corrcoef(b[:-1, axis], b[1:, axis])[0, 1]
        assert abs(r1 - math.exp(-0.2)) < 0.03
        r5 = np.corrcoef(b[:-5, axis], b[5:, axis])[0, 1]
        assert abs(r5 - math.exp(-1.0)) < 0.05
    assert abs(np.corrcoef(b[:, 0], b[:, 1])[0, 1]) < 0.03
    # linear between knots, and the gusts are the whole current here
    mid = f.gust(12.5)
    assert mid == pytest.approx(tuple((b[12] + b[13]) / 2), abs=1e-15)
    assert f.velocity(1.0, 2.0, 12.5) == mid
    assert f.speed_bound_mps() == pytest.approx(6.0 * math.sqrt(2.0) * 0.05)


def test_queries_in_any_order_give_the_same_floats() -> None:
    rng = np.random.default_rng(5)
    pts = [
        (float(x), float(y), float(t))
        for x, y, t in rng.uniform(0.0, 1.0, (400, 3)) * (100.0, 40.0, 900.0)
    ]
    ordered = CurrentField(STORMY, AREA, 3)
    by_time = {p: ordered.velocity(*p) for p in sorted(pts, key=lambda p: p[2])}
    shuffled = CurrentField(STORMY, AREA, 3)
    for i in rng.permutation(len(pts)):
        assert shuffled.velocity(*pts[i]) == by_time[pts[i]]
    late_first = CurrentField(STORMY, AREA, 3)  # the latest query first, then the earliest
    last, first = max(pts, key=lambda p: p[2]), min(pts, key=lambda p: p[2])
    assert late_first.velocity(*last) == by_time[last]
    assert late_first.velocity(*first) == by_time[first]
    assert CurrentField(STORMY, AREA, 4).velocity(*first) != by_time[first]  # another seed


def test_the_speed_bound_holds_over_the_area_and_the_run() -> None:
    f = CurrentField(STORMY, AREA, 2)
    xs, ys = np.meshgrid(np.linspace(0.0, 100.0, 41), np.linspace(0.0, 40.0, 17))
    worst = max(np.max(np.hypot(*f.sample(float(t), xs, ys))) for t in range(0, 1200, 37))
    assert 0.3 < worst <= f.speed_bound_mps()


def test_bad_values_are_config_errors() -> None:
    with pytest.raises(ValueError, match="^radius_m:"):
        EddyConfig(x_m=0.0, y_m=0.0, radius_m=0.0, speed_mps=0.1)
    with pytest.raises(ValueError, match="^speed_mps:"):
        CurrentConfig(speed_mps=-0.1)
    with pytest.raises(ValueError, match="^tidal_amplitude:"):
        CurrentConfig(speed_mps=0.1, tidal_amplitude=0.5)  # no tidal period
    with pytest.raises(ValueError, match="^tau_s:"):
        CurrentConfig(sigma_mps=0.1, tau_s=0.0)


def test_the_old_vehicle_current_names_its_new_place(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ConfigError) as err:
        load_scenario(CONFIGS / "default.toml", ["vehicle.current.y_mps=0.1"])
    assert err.value.key == "vehicle.current" and "world.current" in err.value.problem
    assert main(["check", str(CONFIGS / "default.toml"), "--set", "vehicle.current.y_mps=0.1"]) == 2
    assert "moved to world.current" in capsys.readouterr().err
    s, _ = load_scenario(
        CONFIGS / "default.toml",
        ["world.current.speed_mps=0.25", "world.current.direction_deg=135"],
    )
    assert current_field(s).velocity(0.0, 0.0, 0.0) == pytest.approx(
        (-0.25 / math.sqrt(2.0), 0.25 / math.sqrt(2.0))
    )


def test_every_vehicle_of_a_fleet_moves_in_the_same_water() -> None:
    s, _ = load_scenario(
        CONFIGS / "fleet4.toml",
        [
            "world.current.speed_mps=0.2",
            'world.current.direction="seeded"',
            "world.current.sigma_mps=0.05",
            "world.current.eddies=[{x_m=30.0, y_m=20.0, radius_m=6.0, speed_mps=0.3}]",
        ],
    )
    fields = [current_field(m) for _, m in s.members]
    assert len(fields) == 4
    probes = [(30.0, 26.0, 0.0), (31.5, 12.0, 47.3), (70.0, 20.0, 200.0)]
    for p in probes:
        assert len({f.velocity(*p) for f in fields}) == 1


def test_a_stopped_vehicle_drifts_with_a_uniform_current() -> None:
    # commanded to stop (v = 0 from rest): it keeps its heading and drifts at exactly the
    # current's speed and direction, 0.25 m/s towards 30 degrees
    water = _field(speed_mps=0.25, direction_deg=30.0)
    core = VehicleCore(VehicleConfig(), (10.0, 10.0, 2.0), current=water)
    for k in range(201):
        t = 0.05 * k
        if k % 2 == 0:
            cmd = VelocityCommand(stamp=t, v=0.0, w=0.0, path_id=1)
            core.deliver(Delivery(source="planner", stream="cmd", msg=cmd, t=t))
        core.step(t)
    x, y, theta, v, w = core.pose
    assert (theta, v, w) == (2.0, 0.0, 0.0)
    assert math.hypot(x - 10.0, y - 10.0) == pytest.approx(0.25 * 10.0, abs=1e-9)
    assert math.degrees(math.atan2(y - 10.0, x - 10.0)) == pytest.approx(30.0, abs=1e-9)


def test_the_run_plot_draws_the_current_only_when_there_is_one() -> None:
    from matplotlib.quiver import Quiver

    from common.runtime.model.record import Record
    from services.launcher.plot import run_figure

    calm, _ = load_scenario(CONFIGS / "default.toml")
    ax = run_figure(Record(), calm).axes[0]
    assert not [c for c in ax.collections if isinstance(c, Quiver)]
    assert not [t for t in _legend(ax) if t.startswith("current")]
    flowing, _ = load_scenario(
        CONFIGS / "default.toml",
        ["world.current.speed_mps=0.3", "world.current.direction_deg=90", "run.max_time_s=60"],
    )
    ax = run_figure(Record(), flowing).axes[0]
    (arrows,) = [c for c in ax.collections if isinstance(c, Quiver)]
    assert np.allclose(arrows.U, 0.0) and np.allclose(arrows.V, 0.3)
    assert [t for t in _legend(ax) if t.startswith("current")] == ["current (max 0.30 m/s)"]


def _legend(ax: Any) -> list[str]:
    return [t.get_text() for t in ax.get_legend().get_texts()]
