"""The plottable JSON series of the Foxglove view: each topic's JSON Schema and its encoding.

Plot and Table panels read fields by name (`/plot/cmd.v_mps`), so every series is a flat
JSON object with units in its field names, described by a JSON Schema the app shows. `t` is
the mission time (s, the runtime clock) the values refer to.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass

from common.jsonsafe import JsonObject, JsonValue

# a field's JSON Schema, e.g. {"type": "number"}
Schema = JsonObject

NUM: Schema = {"type": "number"}
INT: Schema = {"type": "integer"}
STR: Schema = {"type": "string"}
BOOL: Schema = {"type": "boolean"}

LINK_FIELDS: dict[str, JsonValue] = {  # each a Schema (JsonValue: it nests in one)
    # a link's counters and modelled delays come from its sender's stats, its measured
    # delays from its receiver's: two services' stats fill one row
    "link": STR,  # source/stream->receiver
    "sent": INT,
    "delivered": INT,
    "dropped_loss": INT,
    "dropped_outage": INT,
    "dropped_queue": INT,
    "duplicated": INT,
    "loss_fraction": NUM,  # every drop over sent
    "delay_p50_s": NUM,  # modelled (the link model's decision)
    "delay_p95_s": NUM,
    "delay_p99_s": NUM,
    "measured_p50_s": NUM,  # hand-over to the receiver's core minus sent
    "measured_p95_s": NUM,
    "measured_max_s": NUM,
}


# a vehicle state (truth or estimate) at its stamp t: pose and velocity
MOTION: dict[str, Schema] = {
    "t": NUM,
    "x_m": NUM,
    "y_m": NUM,
    "theta_rad": NUM,
    "v_mps": NUM,
    "w_radps": NUM,
}


@dataclass(frozen=True)
class JsonSeries:
    """One JSON topic: its name, its schema's title and fields (optional ones may be absent)."""

    topic: str
    title: str
    fields: tuple[tuple[str, Schema], ...]
    optional: frozenset[str] = frozenset()

    @property
    def schema(self) -> bytes:
        """The JSON Schema (draft 2020-12 subset Foxglove reads) of this series."""
        doc = {
            "title": self.title,
            "type": "object",
            "properties": dict(self.fields),
            "required": [name for name, _ in self.fields if name not in self.optional],
        }
        return json.dumps(doc, sort_keys=True).encode()

    def encode(self, values: Mapping[str, JsonValue]) -> bytes:
        """One message of this series; a field the schema does not name is a bug here."""
        unknown = set(values) - {name for name, _ in self.fields}
        if unknown:
            raise ValueError(f"{self.topic}: fields {sorted(unknown)} are not in its schema")
        return json.dumps(values, separators=(",", ":"), allow_nan=False).encode()


def _series(
    topic: str, title: str, optional: tuple[str, ...] = (), /, **fields: Schema
) -> JsonSeries:
    return JsonSeries(topic, title, tuple(fields.items()), frozenset(optional))


CMD = _series(
    "/plot/cmd",
    "tidelink.plot.Command",
    t=NUM,
    v_mps=NUM,
    w_radps=NUM,
    path_id=INT,
    controller=STR,
)
VEHICLE = _series(
    "/plot/vehicle",
    "tidelink.plot.Vehicle",
    t=NUM,
    mode=STR,
    mode_code=INT,  # IDLE 0, RUN 1, HOLD 2, FAILSAFE 3, DONE 4 (plottable)
    mode_since_s=NUM,
    v_applied_mps=NUM,
    w_applied_radps=NUM,
    command_age_s=NUM,
    commands_applied=INT,
    commands_rejected=INT,
    commands_clamped=INT,
)
TRUTH = _series(
    "/plot/truth",
    "tidelink.plot.Truth",
    ("clearance_m",),  # absent in a world without obstacles (+inf)
    **MOTION,
    distance_to_goal_m=NUM,
    clearance_m=NUM,
    collided=BOOL,
)
ESTIMATE = _series(
    "/plot/estimate",
    "tidelink.plot.Estimate",
    **MOTION,
    std_x_m=NUM,
    std_y_m=NUM,
    std_theta_rad=NUM,
)
# an estimate against the truth at its stamp, sent once the truth has reached that stamp
ESTIMATE_ERROR = _series(
    "/plot/estimate_error",
    "tidelink.plot.EstimateError",
    t=NUM,
    error_m=NUM,
    heading_error_rad=NUM,
)
PATH = _series(
    "/plot/path",
    "tidelink.plot.Path",
    t=NUM,
    path_id=INT,
    status=STR,
    ok=INT,  # 1 for OK, 0 for NO_PATH (plottable)
    reason=STR,
    # the plan's reason codes (services/planner/reasons.py): the strategy that made it (a
    # NO_PATH's: why none), and those that ran before it and did not give it, in order
    strategy=STR,
    rejected={"type": "array", "items": STR},
    length_m=NUM,
    f_l=NUM,
    max_curvature_1pm=NUM,
    v_ref_mps=NUM,
    replans=INT,
)
TRACKS = _series(
    "/plot/tracks",
    "tidelink.plot.Tracks",
    t=NUM,
    n_tracks=INT,
    max_std_xy_m=NUM,  # the largest position standard deviation of any track
    n_detections=INT,  # in the latest scan
)
LINKS = _series(
    "/links",
    "tidelink.Links",
    t=NUM,
    links={"type": "array", "items": {"type": "object", "properties": LINK_FIELDS}},
)
RUN_INFO = _series(
    "/run/info",
    "tidelink.RunInfo",
    name=STR,
    vehicle=STR,
    seed=INT,
    controller=STR,
    runtime=STR,
    max_time_s=NUM,
    goal_x_m=NUM,
    goal_y_m=NUM,
)
RUN_END = _series("/run/end", "tidelink.RunEnd", t=NUM, reason=STR, ticks=INT)

ALL: tuple[JsonSeries, ...] = (
    CMD,
    VEHICLE,
    TRUTH,
    ESTIMATE,
    ESTIMATE_ERROR,
    PATH,
    TRACKS,
    LINKS,
    RUN_INFO,
    RUN_END,
)
