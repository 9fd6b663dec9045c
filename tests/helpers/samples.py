"""One message of each wire type with fixed field values (golden vectors, bus exchange tests)."""

from __future__ import annotations

from common.messages import (
    Detection,
    Frame,
    LinkCounters,
    LinkStats,
    MeasuredDelay,
    Message,
    NavFix,
    ObstacleDetections,
    ObstacleTracks,
    Odometry,
    PathAck,
    PathMsg,
    PositionFix,
    RunEnd,
    StateEstimate,
    Tick,
    TickAck,
    Track,
    TruthState,
    VehicleStatus,
    VelocityCommand,
    encode_routing,
    replace,
)

# Envelope fields of every sample (the runtime fills these in real runs).
SOURCE = "sample"
SENT = 12.75


def _diag(n: int, d: float) -> tuple[float, ...]:
    """An n x n row-major covariance with `d` on the diagonal and a small off-diagonal term."""
    return tuple(
        d if i == j else (0.125 if abs(i - j) == 1 else 0.0) for i in range(n) for j in range(n)
    )


def one_of_each() -> list[Message]:
    """One message of every type in MESSAGE_TYPES, in that order, with envelope fields set.

    tests/test_messages_golden.py pins the bytes of these: changing a value here fails it.
    """
    return [
        NavFix(
            stamp=12.5,
            seq=1,
            source=SOURCE,
            sent=SENT,
            x=10.25,
            y=-3.5,
            heading=0.75,
            speed=1.5,
            std_xy=0.5,
            std_heading=0.0625,
            std_speed=0.125,
        ),
        ObstacleDetections(
            stamp=12.5,
            seq=2,
            source=SOURCE,
            sent=SENT,
            detections=(
                Detection(id=0, x=30.0, y=20.0, radius=2.5, std_xy=0.25, std_radius=0.125),
                Detection(id=7, x=-4.5, y=0.0, radius=1.0, std_xy=0.5, std_radius=0.0),
            ),
        ),
        StateEstimate(
            stamp=12.5,
            seq=3,
            source=SOURCE,
            sent=SENT,
            x=10.0,
            y=-3.25,
            theta=0.5,
            v=1.25,
            w=-0.0625,
            covariance=_diag(5, 0.25),
            predicted_s=0.125,
        ),
        ObstacleTracks(
            stamp=12.5,
            seq=4,
            source=SOURCE,
            sent=SENT,
            tracks=(
                Track(
                    id=3,
                    x=40.0,
                    y=15.0,
                    vx=-0.5,
                    vy=0.25,
                    ax=0.0,
                    ay=-0.015625,
                    radius=3.0,
                    covariance=_diag(6, 1.5),
                ),
            ),
        ),
        PathMsg(
            stamp=12.5,
            seq=5,
            source=SOURCE,
            sent=SENT,
            path_id=2,
            status="OK",
            status_since=11.5,
            reason="",
            degree=2,
            control_points=(0.0, 0.0, 5.0, 1.0, 10.0, 0.0, 15.0, 2.0),
            weights=(1.0, 0.75, 1.25, 1.0),
            knots=(0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0),
            waypoints=(0.0, 0.0, 7.5, 0.5, 15.0, 2.0),
            length=15.5,
            f_l=1.03125,
            max_curvature=0.09375,
            v_ref=1.5,
        ),
        VelocityCommand(
            stamp=12.5,
            seq=6,
            source=SOURCE,
            sent=SENT,
            v=1.5,
            w=-0.25,
            path_id=2,
            controller="nurbs",
        ),
        VehicleStatus(
            stamp=12.5,
            seq=7,
            source=SOURCE,
            sent=SENT,
            mode="RUN",
            mode_since=10.25,
            v_applied=1.5,
            w_applied=-0.25,
            command_age=0.125,
            commands_applied=120,
            commands_rejected=1,
            commands_clamped=3,
            rejected_by_reason={"stale": 1},
            delay_s=0.5,
            delay_jitter_s=0.0625,
            delay_samples=118,
        ),
        TruthState(
            stamp=12.5,
            seq=8,
            source=SOURCE,
            sent=SENT,
            x=10.5,
            y=-3.0,
            theta=0.625,
            v=1.5,
            w=-0.25,
            collided=False,
        ),
        LinkStats(
            stamp=12.5,
            seq=9,
            source=SOURCE,
            sent=SENT,
            links=(
                LinkCounters(
                    link="sensor/nav->estimator",
                    sent=100,
                    delivered=95,
                    dropped_loss=4,
                    dropped_outage=1,
                    dropped_queue=0,
                    duplicated=2,
                    delay_p50=0.05,
                    delay_p95=0.125,
                    delay_p99=0.25,
                    bytes_sent=17480,
                ),
            ),
            measured=(
                MeasuredDelay(
                    link="planner/cmd->sensor",
                    delivered=90,
                    delay_p50=0.0625,
                    delay_p95=0.1875,
                    delay_max=0.5,
                ),
            ),
            inputs_dropped={"planner/cmd->sensor": 3},
            inputs_rejected={"cmd.future": 2},
            resets={"vehicle_filter": 1},
            counters={"intent.auv2": 40, "track.auv2": 2},
        ),
        RunEnd(stamp=12.5, seq=1, source=SOURCE, sent=SENT, reason="goal", ticks=250),
        Tick(
            stamp=12.5,
            seq=10,
            source=SOURCE,
            sent=SENT,
            tick=250,
            time_us=12_500_000,
            due=("estimator", "planner"),
            stop=False,
            frames=(
                Frame(
                    source="sensor",
                    stream="nav",
                    seq=125,
                    data=b"\x92\x0c\x81",
                    routing=encode_routing(249, {"estimator": (12_450_000,)}),
                ),
            ),
        ),
        TickAck(
            stamp=12.5,
            seq=11,
            source=SOURCE,
            sent=SENT,
            tick=250,
            service="estimator",
            next_us=12_600_000,
            wakes={"planner": 12_550_000},
            frames=(
                Frame(
                    source="estimator",
                    stream="state",
                    seq=125,
                    data=b"\x92\x0c\x80",
                    routing=encode_routing(250, {"planner": (12_550_000,), "vehicle": ()}),
                ),
            ),
            done=False,
        ),
        Odometry(
            stamp=12.5,
            seq=13,
            source=SOURCE,
            sent=SENT,
            heading=0.75,
            yaw_rate=-0.0625,
            water_speed=1.25,
            bottom_lock=True,
            u_ground=1.5,
            v_ground=-0.125,
            std_heading=0.0078125,
            std_yaw_rate=0.00390625,
            std_water_speed=0.0625,
            std_velocity=0.015625,
        ),
        PositionFix(stamp=12.5, seq=14, source=SOURCE, sent=SENT, x=10.5, y=-3.0, std_xy=0.75),
        PathAck(stamp=12.5, seq=15, source=SOURCE, sent=SENT, path_id=2, since=11.25),
    ]


def variants() -> dict[str, Message]:
    """Further pinned forms of some types, by name: a command carrying future entries, a
    NO_PATH carrying its reason codes."""
    (path,) = (m for m in one_of_each() if isinstance(m, PathMsg))
    return {
        "PathMsg+codes": replace(
            path,
            seq=6,
            path_id=3,
            status="NO_PATH",
            reason="infeasible: no feasible curve",
            strategy="no_curve",
            rejected=("searched", "turned_first", "partway"),
        ),
        "VelocityCommand+sequence": replace(
            VelocityCommand.predictive(
                stamp=12.5,
                v=1.5,
                w=-0.25,
                path_id=2,
                controller="nurbs",
                step_s=0.125,
                v_next=(1.5, 1.25, 0.0),
                w_next=(-0.125, 0.0, 0.5),
            ),
            seq=12,
            source=SOURCE,
            sent=SENT,
        ),
    }
