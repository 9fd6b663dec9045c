"""Open a Zenoh session from a BusConfig, with explicit settings instead of Zenoh defaults."""

from __future__ import annotations

import json

import zenoh

from common.config.bus import BusConfig


def zenoh_config(cfg: BusConfig) -> zenoh.Config:
    """Translate our BusConfig into a zenoh.Config (multicast scouting off unless asked)."""
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(cfg.mode))
    conf.insert_json5("listen/endpoints", json.dumps(list(cfg.listen)))
    conf.insert_json5("connect/endpoints", json.dumps(list(cfg.connect)))
    conf.insert_json5("scouting/multicast/enabled", json.dumps(cfg.multicast_scouting))
    if not cfg.multicast_scouting:
        # nothing to scout for: without this, opening a router session waits out the default
        # 500 ms scouting delay (measured: 0.50 s against 0.002 s)
        conf.insert_json5("scouting/delay", json.dumps(0))
    if cfg.mode != "client":
        # peers/routers: retry connecting so start order between processes does not matter
        conf.insert_json5("connect/timeout_ms", json.dumps(-1))
    conf.insert_json5("connect/exit_on_failure", json.dumps(False))
    return conf


def open_session(cfg: BusConfig) -> zenoh.Session:
    """Open a session; the caller must close it (Bus does, deterministically).

    ConnectionError (an OSError: the CLI prints it as one line) when a client cannot reach
    its router, or the endpoints are refused, naming them."""
    try:
        return zenoh.open(zenoh_config(cfg))
    except zenoh.ZError as exc:
        where = ", ".join(cfg.connect or cfg.listen) or "(no endpoint)"
        what = "reach the router at" if cfg.mode == "client" else "open a session on"
        why = str(exc).split(" at /", 1)[0]  # drop the Rust source location
        raise ConnectionError(f"cannot {what} {where}: {why}") from None
