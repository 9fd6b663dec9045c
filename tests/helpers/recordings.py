"""What recording tests compare: frames, per-stream prefixes, `tidelink metrics`."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path
from typing import Any

from helpers.launch_proc import Tidelink
from services.recording.reader import Recording

WAIT_S = 90.0


def metrics_of(path: Path) -> dict[str, Any]:
    """A run's metrics.json."""
    return dict(json.loads(path.read_text()))


def without_wall(m: dict[str, Any]) -> dict[str, Any]:
    """Metrics but the wall time, which a recording cannot know."""
    return {k: v for k, v in m.items() if k != "wall_s"}


def tidelink_metrics(mcap: Path) -> dict[str, Any]:
    """`tidelink metrics FILE --json`: the metrics recomputed from a recording alone."""
    with Tidelink("metrics", str(mcap), "--json") as t:
        assert t.wait(WAIT_S) == 0, t.stderr
        return dict(json.loads(t.stdout))


def frames(rec: Recording) -> Counter[tuple[str, str, bytes, bytes | None]]:
    """Every frame of a recording, byte for byte, attachments included."""
    return Counter((f.service, f.stream, f.payload, f.attachment) for f in rec.frames)


def by_stream(frames: list[Any]) -> dict[str, list[bytes]]:
    """Payloads per `service/stream`, in recorded order."""
    out: dict[str, list[bytes]] = {}
    for f in frames:
        out.setdefault(f"{f.service}/{f.stream}", []).append(f.payload)
    return out


def is_prefix(part: dict[str, list[bytes]], whole: dict[str, list[bytes]]) -> bool:
    """Each stream of `part` is the start of the same stream of `whole`."""
    return all(whole[k][: len(v)] == v for k, v in part.items())
