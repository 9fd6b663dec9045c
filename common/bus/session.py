"""Open a Zenoh session from a BusConfig, with explicit settings instead of Zenoh defaults."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import zenoh

from common.config.bus import BusConfig

if TYPE_CHECKING:
    from common.bus.certs import Credentials


ROUTER_BLOCK_CLOSE_US = 3_000_000
# A router waits this long (us) for room in a client's queue before dropping a DROP sample for
# it (Zenoh's default: 1000). The wait is spent on the task that reads the publisher's link:
# behind a stopped watcher, 1 ms per watch copy was most of a second per second of the run's
# copies, and the link that carries them fell behind (docs/notes/0045-watchers-off-the-loop.md)
ROUTER_WAIT_BEFORE_DROP_US = 50
# Zenoh's RX runtime: the threads that read every link of a router and route what arrives.
# Closing the session of a client that stopped reading (its lease expired while its socket
# was full) holds one of them for up to 10 s; with Zenoh's default of 2, two watchers frozen
# together (a laptop put to sleep) stalled every stream of the run for 10 s
# (docs/notes/0045-watchers-off-the-loop.md). ZENOH_RUNTIME set by the user wins.
ROUTER_RUNTIME = "(rx: (worker_threads: 8))"
RUNTIME_ENV = "ZENOH_RUNTIME"


def zenoh_config(
    cfg: BusConfig,
    *,
    identity: str | None = None,
    access_control: Mapping[str, object] | None = None,
) -> zenoh.Config:
    """Translate our BusConfig into a zenoh.Config (multicast scouting off unless asked).

    Under mTLS the session presents `identity`'s certificate (validated first:
    CredentialsError names a missing, mismatched, foreign or expired file); a router may
    enforce `access_control` (Zenoh's ACL object, common/runtime/distributed/acl.py)."""
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(cfg.mode))
    conf.insert_json5("listen/endpoints", json.dumps([cfg.endpoint(e) for e in cfg.listen]))
    conf.insert_json5("connect/endpoints", json.dumps([cfg.endpoint(e) for e in cfg.connect]))
    conf.insert_json5("scouting/multicast/enabled", json.dumps(cfg.multicast_scouting))
    if not cfg.multicast_scouting:
        # nothing to scout for: without this, opening a router session waits out Zenoh's
        # default 500 ms scouting delay
        conf.insert_json5("scouting/delay", json.dumps(0))
    if cfg.mode != "client":
        # peers/routers: retry connecting so start order between processes does not matter
        conf.insert_json5("connect/timeout_ms", json.dumps(-1))
    conf.insert_json5("connect/exit_on_failure", json.dumps(False))
    conf.insert_json5("transport/link/tx/lease", json.dumps(round(cfg.lease_s * 1000)))
    if cfg.mode == "client":
        # a client cut off from its router retries every second, not after a backoff that
        # doubles up to 4 s (Zenoh's default): once a host's link is back its services
        # rejoin within a second (docs/notes/0029-a-host-cut-off-from-the-router.md)
        retry = {"period_init_ms": 1000, "period_max_ms": 1000, "period_increase_factor": 1}
        conf.insert_json5("connect/retry", json.dumps(retry))
    if cfg.mode == "router":
        # a router forwards the control streams with congestion BLOCK: a client whose host
        # is cut off fills its queue and would hold every other client's samples up to the
        # default 5 s; close that session after 3 s instead (the client reconnects). Not
        # shorter: a watcher reading a burst slowly but steadily must keep its session (a
        # blocked TCP sender may wake only once a third of its send buffer has drained,
        # megabytes at a slow reader's pace) (docs/notes/0029-a-host-cut-off-from-the-router.md)
        conf.insert_json5(
            "transport/link/tx/queue/congestion_control/block/wait_before_close",
            json.dumps(ROUTER_BLOCK_CLOSE_US),
        )
        conf.insert_json5(
            "transport/link/tx/queue/congestion_control/drop/wait_before_drop",
            json.dumps(ROUTER_WAIT_BEFORE_DROP_US),
        )
    if cfg.secured:
        from common.bus.certs import tls_settings

        tls = tls_settings(_credentials(cfg, identity), listen=bool(cfg.listen))
        conf.insert_json5("transport/link/tls", json.dumps(tls))
    if access_control is not None:
        conf.insert_json5("access_control", json.dumps(dict(access_control)))
    return conf


def open_session(
    cfg: BusConfig,
    *,
    identity: str | None = None,
    access_control: Mapping[str, object] | None = None,
) -> zenoh.Session:
    """Open a session; the caller must close it (Bus does, deterministically).

    ConnectionError (an OSError: the CLI prints it as one line) when a client cannot reach
    its router, or the endpoints are refused, naming them."""
    conf = zenoh_config(cfg, identity=identity, access_control=access_control)
    if cfg.mode == "router":
        # read when this process's first session starts Zenoh's runtimes (a router is the first)
        os.environ.setdefault(RUNTIME_ENV, ROUTER_RUNTIME)
    try:
        return zenoh.open(conf)
    except zenoh.ZError as exc:
        endpoints = [cfg.endpoint(e) for e in cfg.connect or cfg.listen]
        what = "reach the router at" if cfg.mode == "client" else "open a session on"
        why = str(exc).split(" at /", 1)[0].strip()  # drop the Rust source location
        if cfg.mode == "client" and endpoints:
            # Zenoh does not say why; one handshake of our own tells the causes apart
            from common.bus.diagnose import why_unreachable

            creds = _credentials(cfg, identity) if cfg.secured else None
            because = why_unreachable(endpoints[0], creds)
            why = f"{because} ({why})" if because else why
        raise ConnectionError(
            f"cannot {what} {', '.join(endpoints) or '(no endpoint)'}: {why}"
        ) from None


def _credentials(cfg: BusConfig, identity: str | None) -> Credentials:
    """The validated certificate files of `identity` (CredentialsError names a bad one)."""
    from common.bus.certs import load_credentials

    if identity is None:
        raise ValueError("an mTLS session needs an identity (whose certificate to present)")
    return load_credentials(Path(cfg.certs), identity)
