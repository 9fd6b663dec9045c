"""The typed, frozen message classes of the tidelink wire (one per stream kind)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Annotated, Literal

import msgspec

from common.messages.base import (
    Message,
    WireError,
    WireRecord,
    check_non_negative,
    check_range,
)

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
        check_non_negative(self, "", "std_xy", "std_heading", "std_speed")


class Odometry(Message, frozen=True, kw_only=True):
    """Dead-reckoning sensors of an AUV, sampled together: the AHRS heading and yaw rate, the
    speed through the water of the propeller's rpm model, and the DVL's velocity over ground
    in the body frame (bottom track; `bottom_lock` False when the DVL has lost the seabed, and
    then u_ground and v_ground mean nothing)."""

    heading: float  # rad, AHRS (noise and a bias)
    yaw_rate: float  # rad/s, AHRS gyro
    water_speed: float  # m/s, surge through the water from the propeller's rpm
    bottom_lock: bool
    u_ground: float  # m/s, forward over ground (body frame)
    v_ground: float  # m/s, to port over ground (body frame)
    std_heading: float
    std_yaw_rate: float
    std_water_speed: float
    std_velocity: float

    def validate(self) -> None:
        check_non_negative(
            self, "", "std_heading", "std_yaw_rate", "std_water_speed", "std_velocity"
        )


class PositionFix(Message, frozen=True, kw_only=True):
    """An absolute position fix (USBL or LBL), stamped when the vehicle was ranged: it reaches
    the estimator over the acoustic link, seconds late, and may be an outlier."""

    x: float
    y: float
    std_xy: float

    def validate(self) -> None:
        check_non_negative(self, "", "std_xy")


class Detection(WireRecord, frozen=True, kw_only=True):
    """One detected obstacle: its id, noisy position and radius, and their noise."""

    id: int
    x: float
    y: float
    radius: float
    std_xy: float
    std_radius: float

    def validate(self) -> None:
        check_non_negative(self, "detection.", "id", "radius", "std_xy", "std_radius")


class ObstacleDetections(Message, frozen=True, kw_only=True):
    """Obstacle detections (sonar/camera) of one scan, stamped at its sampling time."""

    detections: tuple[Detection, ...]


class StateEstimate(Message, frozen=True, kw_only=True):
    """The estimated vehicle state (x, y, theta, v, w) at `stamp` and its 5x5 covariance,
    row-major.

    `predicted_s` says how far the estimator carried its newest fused fix forward to `stamp`
    (at constant speed and yaw rate, eq. (7)): the information in the estimate is that old on
    top of its own age, and a receiver that knows more of the motion since (the commands
    sent) can go back along that arc to the fix and predict from there. 0 before any fix.
    """

    x: float
    y: float
    theta: float
    v: float
    w: float
    covariance: tuple[float, ...]
    predicted_s: float = 0.0  # s, >= 0
    # the ocean current the estimator believes carries the vehicle (world frame, m/s):
    # ground velocity = v (cos theta, sin theta) + current
    current_x: float = 0.0
    current_y: float = 0.0
    current_std: float = 0.0  # m/s: the root mean of the current's two variances
    sway: float = 0.0  # m/s: the hull's sway through the water (to port), a sideslip in turns
    sway_std: float = 0.0  # m/s

    def validate(self) -> None:
        _check_cov("covariance", self.covariance, 5)
        check_range("predicted_s", self.predicted_s, 0.0)
        check_range("current_std", self.current_std, 0.0)
        check_range("sway_std", self.sway_std, 0.0)


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
        check_non_negative(self, "track.", "id", "radius")
        _check_cov("track.covariance", self.covariance, 6)


class ObstacleTracks(Message, frozen=True, kw_only=True):
    """All obstacle tracks the estimator holds at `stamp`."""

    tracks: tuple[Track, ...]


class PathMsg(Message, frozen=True, kw_only=True, omit_defaults=True):
    """A planned path as a NURBS curve, or a NO_PATH status with its reason.

    `strategy` and `rejected` are the plan's reason codes (services/planner/reasons.py, wire
    version 10); a path without them (the defaults "" and ()) leaves them out of the frame
    (omit_defaults; see VelocityCommand for how msgspec tells a default)."""

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
    strategy: str = ""  # the strategy that made the plan; a NO_PATH's: why none
    rejected: tuple[str, ...] = ()  # the strategies that ran before it and did not give it

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
        check_non_negative(self, "", "length", "f_l", "max_curvature", "v_ref")


class PathAck(Message, frozen=True, kw_only=True):
    """The onboard tracker's word on the path it follows: `path_id` (0: none yet), taken at
    `since` (s, runtime clock), sent on every path message it receives, so the planner knows
    when a path reached it however late or lossy the link (wire version 11)."""

    path_id: int
    since: float = 0.0

    def validate(self) -> None:
        check_range("path_id", self.path_id, 0)
        check_range("since", self.since, 0.0)


# Bounds of a command's sequence of future entries (packet-based predictive control). The
# wire refuses more entries (a hostile 10^6-entry frame is refused from its array header, before
# a single entry is read); the vehicle accepts at most `max_sequence_len` of them.
MAX_SEQUENCE_LEN = 1000
SEQUENCE_STEP_MIN_MS = 1  # the step between entries is a whole number of milliseconds
SEQUENCE_STEP_MAX_MS = 10_000
# a future entry travels in thousandths (mm/s, mrad/s); |entry| <= 100 m/s or rad/s (a sanity
# bound only: the vehicle clamps to its eq. (11) bounds)
SEQUENCE_UNITS_PER_SI = 1000
_Q_MAX = 100 * SEQUENCE_UNITS_PER_SI
_Entries = Annotated[
    tuple[Annotated[int, msgspec.Meta(ge=-_Q_MAX, le=_Q_MAX)], ...],
    msgspec.Meta(max_length=MAX_SEQUENCE_LEN),
]


def _quantised(name: str, xs: Sequence[float]) -> tuple[int, ...]:
    """Entries in SI units as integers in thousandths (rounded half to even)."""
    try:
        # (a list comprehension: a generator resumed per entry costs a fifth more)
        return tuple([round(x * SEQUENCE_UNITS_PER_SI) for x in xs])
    except (ValueError, OverflowError) as exc:  # NaN, infinity
        raise WireError(f"{name}: {exc}") from None


_INT_ONLY = frozenset((int,))


class VelocityCommand(Message, frozen=True, kw_only=True, omit_defaults=True):
    """A velocity command to the vehicle: surge speed v (m/s) and yaw rate w (rad/s), in force
    from `stamp`, optionally followed by a sequence of future commands (packet-based
    predictive control).

    Entry 0 is (v, w), in force from `stamp`; entry k = 1..n is (v_next_mmps[k-1] mm/s,
    w_next_mradps[k-1] mrad/s), in force from stamp + k * step_s, step_s = step_ms / 1000
    (the properties v_next, w_next and step_s give them in SI units). A fixed step rather
    than explicit times: one number instead of one per entry, and the entry times cannot be
    out of order. The sequence is integers (1 ms; 1 mm/s, 1 mrad/s: far below what the
    actuators resolve), 1-3 bytes each in MessagePack where a float takes 9. With no future
    entries (n = 0, step_ms = 0) this is the single command of wire version 4, byte for byte
    apart from the version: fields at their default are left out of the frame
    (omit_defaults; msgspec tells a default by identity, which holds for the integer 0 and
    the empty tuple however they were computed, not for a float 0.0), so an absent sequence
    costs nothing.
    """

    v: float
    w: float
    path_id: int
    controller: str = ""
    step_ms: int = 0  # time between entries (ms); 0 without future entries
    v_next_mmps: _Entries = ()
    w_next_mradps: _Entries = ()

    @classmethod
    def predictive(
        cls,
        *,
        stamp: float,
        v: float,
        w: float,
        path_id: int,
        controller: str = "",
        step_s: float = 0.0,
        v_next: Sequence[float] = (),
        w_next: Sequence[float] = (),
    ) -> VelocityCommand:
        """A command with future entries given in m/s and rad/s (quantised for the wire) at
        a step of step_s, a whole number of milliseconds."""
        step_ms = round(step_s * 1000) if math.isfinite(step_s) else -1
        if abs(step_ms - step_s * 1000) > 1e-6:
            raise WireError(f"step_s: {step_s!r} is not a whole number of milliseconds")
        return cls(
            stamp=stamp,
            v=v,
            w=w,
            path_id=path_id,
            controller=controller,
            step_ms=step_ms,
            v_next_mmps=_quantised("v_next", v_next),
            w_next_mradps=_quantised("w_next", w_next),
        )

    @property
    def step_s(self) -> float:
        """Time between entries (s)."""
        return self.step_ms / 1000

    @property
    def horizon(self) -> int:
        """Number n of future entries (0: a single command)."""
        return len(self.v_next_mmps)

    @property
    def v_next(self) -> tuple[float, ...]:
        """Future surge speeds (m/s) of entries 1..n."""
        # (a list comprehension: a third faster than a generator; a command's future entries
        # are read by the vehicle at every delivery and by the planner's timeline)
        return tuple([q / SEQUENCE_UNITS_PER_SI for q in self.v_next_mmps])

    @property
    def w_next(self) -> tuple[float, ...]:
        """Future yaw rates (rad/s) of entries 1..n."""
        return tuple([q / SEQUENCE_UNITS_PER_SI for q in self.w_next_mradps])  # (as v_next)

    def validate(self) -> None:
        check_range("path_id", self.path_id, 0)
        n = len(self.v_next_mmps)
        if len(self.w_next_mradps) != n:
            raise WireError(
                f"w_next_mradps: expected {n} entries (as v_next_mmps), "
                f"got {len(self.w_next_mradps)}"
            )
        if n == 0:
            if self.step_ms != 0:
                raise WireError(f"step_ms: {self.step_ms!r} without future entries (must be 0)")
            return
        # checked when built (msgspec checks these itself when it decodes)
        if n > MAX_SEQUENCE_LEN:
            raise WireError(f"v_next_mmps: {n} future entries, at most {MAX_SEQUENCE_LEN}")
        check_range("step_ms", self.step_ms, SEQUENCE_STEP_MIN_MS, SEQUENCE_STEP_MAX_MS)
        for name in ("v_next_mmps", "w_next_mradps"):
            qs = getattr(self, name)
            if not set(map(type, qs)) <= _INT_ONLY:  # every entry exactly an int (not a bool)
                raise WireError(f"{name}: entries must be integers")
            check_range(f"{name} entry", min(qs), -_Q_MAX)
            check_range(f"{name} entry", max(qs), hi=_Q_MAX)


class VehicleStatus(Message, frozen=True, kw_only=True):
    """The vehicle's mode (incl. FAILSAFE), the command it applies and its age, its command
    counters, and the one-way delay it observes on commands.

    `command_age` is t minus the start of the entry in force (for a single command: t minus
    its stamp). The delay figures are over the last `vehicle.watchdog.delay_window` commands
    from the commander that passed the source, finiteness, future and shape checks (late,
    overtaken and duplicated ones included: their delay is real), each sample being delivery
    time minus stamp (mission time; the planner stamps a command when it sends it, so this is
    the command link's one-way delay): `delay_s` is their median, `delay_jitter_s` 1.4826 x
    their median absolute deviation from it (the standard deviation, for normal jitter), both 0
    before the first sample; `delay_samples` counts every sample so far. A single outlier moves
    either figure by at most one rank of the window.
    """

    mode: VehicleMode
    mode_since: float = 0.0  # when the vehicle entered `mode` (the last mode change)
    v_applied: float
    w_applied: float
    command_age: float
    commands_applied: int
    commands_rejected: int
    commands_clamped: int
    rejected_by_reason: dict[str, int] = msgspec.field(default_factory=dict)
    delay_s: float = 0.0
    delay_jitter_s: float = 0.0
    delay_samples: int = 0

    def validate(self) -> None:
        check_non_negative(
            self,
            "",
            "command_age",
            "delay_jitter_s",
            "commands_applied",
            "commands_rejected",
            "commands_clamped",
            "delay_samples",
        )
        for reason, n in self.rejected_by_reason.items():
            check_range(f"rejected_by_reason[{reason!r}]", n, 0)


class TruthState(Message, frozen=True, kw_only=True):
    """The vehicle's true state (simulation only): pose, speeds and any collision.

    v and sway are the hull's surge and sway speed through the water (body frame), w its yaw
    rate; current_x, current_y the current at the hull (world frame): the velocity over
    ground is v (cos theta, sin theta) + sway (-sin theta, cos theta) + current.
    """

    x: float
    y: float
    theta: float
    v: float
    w: float
    collided: bool = False
    sway: float = 0.0
    current_x: float = 0.0
    current_y: float = 0.0

    @property
    def ground_velocity(self) -> tuple[float, float]:
        """Velocity over ground (world frame, m/s)."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        return (
            self.v * c - self.sway * s + self.current_x,
            self.v * s + self.sway * c + self.current_y,
        )


# what a link counts, as LinkCounters and the netmodel's snapshots name it
LINK_COUNTS = ("sent", "delivered", "dropped_loss", "dropped_outage", "dropped_queue", "duplicated")


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
    bytes_sent: int = 0  # encoded bytes of every message offered to the link

    def counts(self) -> dict[str, int | float]:
        """The counters and modelled delays as a table row (metrics' link_stats, Foxglove's
        /links): sent, delivered, each drop, duplicates, delay_p50/p95/p99_s."""
        row: dict[str, int | float] = {name: getattr(self, name) for name in LINK_COUNTS}
        delays = (self.delay_p50, self.delay_p95, self.delay_p99)
        row.update(zip(("delay_p50_s", "delay_p95_s", "delay_p99_s"), delays, strict=True))
        return row

    def validate(self) -> None:
        check_non_negative(
            self, "link.", *LINK_COUNTS, "bytes_sent", "delay_p50", "delay_p95", "delay_p99"
        )


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
        check_non_negative(self, "measured.", "delivered", "delay_p50", "delay_p95", "delay_max")


class LinkStats(Message, frozen=True, kw_only=True):
    """Per-link statistics a service publishes on `.../<service>/stats`: counters of its
    outgoing links, the delays it measured on its incoming ones, and how its inputs fared:
    deliveries dropped because an input's queue was full (by link), inputs its core rejected
    as implausible (by '<stream>.<reason>'), filters its core restarted (by filter), and what
    else its core or runtime counts (by name: a fleet planner's steps by intent or by track,
    per vehicle; a realtime service's loop times in us, 'loop.step_p50_us' ...)."""

    links: tuple[LinkCounters, ...]
    measured: tuple[MeasuredDelay, ...] = ()
    inputs_dropped: dict[str, int] = msgspec.field(default_factory=dict)
    inputs_rejected: dict[str, int] = msgspec.field(default_factory=dict)
    resets: dict[str, int] = msgspec.field(default_factory=dict)
    counters: dict[str, int] = msgspec.field(default_factory=dict)

    def validate(self) -> None:
        for name in ("inputs_dropped", "inputs_rejected", "resets", "counters"):
            for key, n in getattr(self, name).items():
                check_range(f"{name}[{key!r}]", n, 0)


class RunEnd(Message, frozen=True, kw_only=True):
    """The clock's announcement that the run ended at `stamp`: why, after how many ticks."""

    reason: str
    ticks: int

    def validate(self) -> None:
        check_range("ticks", self.ticks, 0)


class Frame(WireRecord, frozen=True, kw_only=True, array_like=True):
    """One message a service published in a lockstep tick, as it would cross the wire on its
    stream: the encoded message (whose seq it repeats) and its routing attachment
    (encode_routing). An ack carries the frames its service published in the tick, a tick
    those its services read that were published since each was last ticked
    (common/runtime/distributed/lockstep.py). An array on the wire, [source, stream, seq, data,
    routing]: a tick may carry many."""

    source: str
    stream: str
    seq: int
    data: bytes
    routing: bytes

    def validate(self) -> None:
        if not self.source or not self.stream:
            raise WireError("frame: source and stream must not be empty")
        check_range("frame.seq", self.seq, 1)


class Tick(Message, frozen=True, kw_only=True):
    """The clock: advance to virtual time `time_us` (lockstep) or tell the time (realtime)."""

    tick: int
    time_us: int
    due: tuple[str, ...] = ()  # the services that run this tick (the others have nothing due)
    stop: bool = False  # end of run: publish final statistics, acknowledge and exit
    # lockstep: what the due services read, published since each was last ticked
    frames: tuple[Frame, ...] = ()

    def validate(self) -> None:
        check_range("tick", self.tick, 0)
        check_range("time_us", self.time_us, 0)


class TickAck(Message, frozen=True, kw_only=True):
    """Lockstep clock: a service finished `tick`; what it published; its next event time."""

    tick: int
    service: str
    next_us: int  # next time this service needs a tick (its next step or wake delivery)
    # receiver -> earliest wake delivery
    wakes: dict[str, int] = msgspec.field(default_factory=dict)
    frames: tuple[Frame, ...] = ()  # what it published in the tick, in order
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
    Odometry,
    PositionFix,
    PathAck,
)
