"""The typed, frozen message classes of the tidelink wire (one per stream kind)."""

from __future__ import annotations

from typing import Literal

import msgspec

from common.messages.base import Message, WireError, WireRecord, check_range

VehicleMode = Literal["IDLE", "RUN", "HOLD", "FAILSAFE", "DONE"]
PathStatus = Literal["OK", "NO_PATH"]


def _check_cov(name: str, cov: tuple[float, ...], n: int) -> None:
    if len(cov) != n * n:
        raise WireError(f"{name}: expected {n * n} entries ({n}x{n} row-major), got {len(cov)}")
    for i in range(n):
        if cov[i * n + i] < 0.0:
            raise WireError(f"{name}: diagonal entry {i} is negative ({cov[i * n + i]!r})")


class NavFix(Message, frozen=True, kw_only=True):
    """A navigation fix: position (USBL/GPS-like), heading (compass), speed (DVL), with noise."""

    x: float
    y: float
    heading: float
    speed: float
    std_xy: float
    std_heading: float
    std_speed: float

    def validate(self) -> None:
        if self.std_xy >= 0.0 and self.std_heading >= 0.0 and self.std_speed >= 0.0:
            return  # the common case, without a call per field
        for name in ("std_xy", "std_heading", "std_speed"):
            check_range(name, getattr(self, name), 0.0)


class Detection(WireRecord, frozen=True, kw_only=True):
    """One detected obstacle: its id, noisy position and radius, and their noise."""

    id: int
    x: float
    y: float
    radius: float
    std_xy: float
    std_radius: float

    def validate(self) -> None:
        check_range("detection.id", self.id, 0)
        check_range("detection.radius", self.radius, 0.0)
        check_range("detection.std_xy", self.std_xy, 0.0)
        check_range("detection.std_radius", self.std_radius, 0.0)


class ObstacleDetections(Message, frozen=True, kw_only=True):
    """Obstacle detections (sonar/camera) of one scan, stamped at its sampling time."""

    detections: tuple[Detection, ...]


class StateEstimate(Message, frozen=True, kw_only=True):
    """The estimated vehicle state (x, y, theta, v, w) and its 5x5 covariance, row-major."""

    x: float
    y: float
    theta: float
    v: float
    w: float
    covariance: tuple[float, ...]

    def validate(self) -> None:
        _check_cov("covariance", self.covariance, 5)


class Track(WireRecord, frozen=True, kw_only=True):
    """One tracked obstacle: position, velocity, acceleration, radius and 6x6 covariance."""

    id: int
    x: float
    y: float
    vx: float
    vy: float
    ax: float
    ay: float
    radius: float
    covariance: tuple[float, ...]

    def validate(self) -> None:
        check_range("track.id", self.id, 0)
        check_range("track.radius", self.radius, 0.0)
        _check_cov("track.covariance", self.covariance, 6)


class ObstacleTracks(Message, frozen=True, kw_only=True):
    """All obstacle tracks the estimator holds at `stamp`."""

    tracks: tuple[Track, ...]


class PathMsg(Message, frozen=True, kw_only=True):
    """A planned path as a NURBS curve, or a NO_PATH status with its reason."""

    path_id: int
    status: PathStatus
    # when the planner began publishing `status` without a break (s, runtime clock): for a
    # NO_PATH, when it first failed to plan; stamp - status_since is how long it persists
    status_since: float = 0.0
    reason: str
    degree: int
    control_points: tuple[float, ...]  # flat x0, y0, x1, y1, ...
    weights: tuple[float, ...]
    knots: tuple[float, ...]
    waypoints: tuple[float, ...]  # the grid (graph) path it was fitted to, flat x, y pairs
    length: float
    f_l: float
    max_curvature: float
    v_ref: float

    def validate(self) -> None:
        check_range("path_id", self.path_id, 0)
        if self.status == "NO_PATH":
            return
        if len(self.control_points) % 2:
            raise WireError("control_points: odd number of coordinates")
        if len(self.waypoints) % 2:
            raise WireError("waypoints: odd number of coordinates")
        n = len(self.control_points) // 2
        check_range("degree", self.degree, 1, 10)
        if n <= self.degree:
            raise WireError(f"control_points: {n} points cannot carry a degree-{self.degree} curve")
        if len(self.weights) != n:
            raise WireError(
                f"weights: expected {n} (one per control point), got {len(self.weights)}"
            )
        if len(self.knots) != n + self.degree + 1:
            raise WireError(
                f"knots: expected {n + self.degree + 1} (points + degree + 1), "
                f"got {len(self.knots)}"
            )
        if any(w <= 0.0 for w in self.weights):
            raise WireError("weights: every weight must be > 0")
        if any(b < a for a, b in zip(self.knots, self.knots[1:], strict=False)):
            raise WireError("knots: must be non-decreasing")
        check_range("length", self.length, 0.0)
        check_range("f_l", self.f_l, 0.0)
        check_range("max_curvature", self.max_curvature, 0.0)
        check_range("v_ref", self.v_ref, 0.0)


class VelocityCommand(Message, frozen=True, kw_only=True):
    """A velocity command to the vehicle: surge speed v (m/s) and yaw rate w (rad/s)."""

    v: float
    w: float
    path_id: int
    controller: str = ""

    def validate(self) -> None:
        check_range("path_id", self.path_id, 0)


class VehicleStatus(Message, frozen=True, kw_only=True):
    """The vehicle's mode (incl. FAILSAFE), the command it applies and its age."""

    mode: VehicleMode
    mode_since: float = 0.0  # when the vehicle entered `mode` (the last mode change)
    v_applied: float
    w_applied: float
    command_age: float
    commands_applied: int
    commands_rejected: int
    commands_clamped: int
    rejected_by_reason: dict[str, int] = msgspec.field(default_factory=dict)

    def validate(self) -> None:
        check_range("command_age", self.command_age, 0.0)
        for name in ("commands_applied", "commands_rejected", "commands_clamped"):
            check_range(name, getattr(self, name), 0)
        for reason, n in self.rejected_by_reason.items():
            check_range(f"rejected_by_reason[{reason!r}]", n, 0)


class TruthState(Message, frozen=True, kw_only=True):
    """The vehicle's true state (simulation only): pose, speeds and any collision."""

    x: float
    y: float
    theta: float
    v: float
    w: float
    collided: bool = False


class LinkCounters(WireRecord, frozen=True, kw_only=True):
    """Counters of one modelled link (one stream as seen by one receiving service)."""

    link: str
    sent: int
    delivered: int
    dropped_loss: int
    dropped_outage: int
    dropped_queue: int
    duplicated: int
    delay_p50: float  # modelled delay (the link model's decision), first copy
    delay_p95: float
    delay_p99: float

    def validate(self) -> None:
        for name in ("sent", "delivered", "dropped_loss", "dropped_outage", "dropped_queue"):
            check_range(f"link.{name}", getattr(self, name), 0)
        check_range("link.duplicated", self.duplicated, 0)
        for name in ("delay_p50", "delay_p95", "delay_p99"):
            check_range(f"link.{name}", getattr(self, name), 0.0)


class MeasuredDelay(WireRecord, frozen=True, kw_only=True):
    """Delays a receiving service measured on one incoming link: the time each message was
    handed to its core minus its `sent` stamp. Equal to the modelled delay in virtual time
    (inproc, lockstep); in realtime it adds the bus's transit and any lateness."""

    link: str
    delivered: int
    delay_p50: float
    delay_p95: float
    delay_max: float

    def validate(self) -> None:
        check_range("measured.delivered", self.delivered, 0)
        for name in ("delay_p50", "delay_p95", "delay_max"):
            check_range(f"measured.{name}", getattr(self, name), 0.0)


class LinkStats(Message, frozen=True, kw_only=True):
    """Per-link statistics a service publishes on `.../<service>/stats`: counters of its
    outgoing links, the delays it measured on its incoming ones, and how its inputs fared:
    deliveries dropped because an input's queue was full (by link), inputs its core rejected
    as implausible (by '<stream>.<reason>'), filters its core restarted (by filter)."""

    links: tuple[LinkCounters, ...]
    measured: tuple[MeasuredDelay, ...] = ()
    inputs_dropped: dict[str, int] = msgspec.field(default_factory=dict)
    inputs_rejected: dict[str, int] = msgspec.field(default_factory=dict)
    resets: dict[str, int] = msgspec.field(default_factory=dict)

    def validate(self) -> None:
        for name in ("inputs_dropped", "inputs_rejected", "resets"):
            for key, n in getattr(self, name).items():
                check_range(f"{name}[{key!r}]", n, 0)


class RunEnd(Message, frozen=True, kw_only=True):
    """The clock's announcement that the run ended at `stamp`: why, after how many ticks."""

    reason: str
    ticks: int

    def validate(self) -> None:
        check_range("ticks", self.ticks, 0)


class Tick(Message, frozen=True, kw_only=True):
    """Lockstep clock: advance to virtual time `time_us`; watermarks of every stream so far."""

    tick: int
    time_us: int
    watermarks: dict[str, int]
    due: tuple[str, ...] = ()  # the services that run this tick (the others have nothing due)
    stop: bool = False  # end of run: publish final statistics, acknowledge and exit

    def validate(self) -> None:
        check_range("tick", self.tick, 0)
        check_range("time_us", self.time_us, 0)


class TickAck(Message, frozen=True, kw_only=True):
    """Lockstep clock: a service finished `tick`; what it published; its next event time."""

    tick: int
    service: str
    published: dict[str, int]  # stream key -> last seq published so far
    next_us: int  # next time this service needs a tick (its next step or wake delivery)
    # receiver -> earliest wake delivery
    wakes: dict[str, int] = msgspec.field(default_factory=dict)
    done: bool = False  # the service asks the run to end (e.g. the vehicle reached the goal)

    def validate(self) -> None:
        check_range("tick", self.tick, 0)
        check_range("next_us", self.next_us, 0)
        if not self.service:
            raise WireError("service: must not be empty")


MESSAGE_TYPES: tuple[type[Message], ...] = (
    NavFix,
    ObstacleDetections,
    StateEstimate,
    ObstacleTracks,
    PathMsg,
    VelocityCommand,
    VehicleStatus,
    TruthState,
    LinkStats,
    RunEnd,
    Tick,
    TickAck,
)
