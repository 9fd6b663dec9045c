"""Start the run's Zenoh router (`tidelink router`) as a supervised process and wait for it."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from common.runtime.processes.children import connectable, free_port, how_it_ended
from common.runtime.processes.signals import Interrupted
from common.runtime.processes.supervisor import Supervisor

ROUTER = "router"
READY_LINE = "zenoh router listening on"  # printed by `tidelink router` once it listens


def start_router(
    sup: Supervisor,
    listen: tuple[str, ...],
    *,
    timeout_s: float = 30.0,
    cancelled: Callable[[], bool] = lambda: False,
    certs: str | None = None,
    acl: Path | None = None,
) -> str:
    """Start the router listening on `listen` (default: a free loopback port) and wait until it
    says it listens; returns the endpoint local processes connect to. With `certs` it listens
    on TLS only, as the router identity, enforcing the access control in the `acl` file."""
    if not listen:
        listen = (f"tcp/127.0.0.1:{free_port()}",)
    args = ["-m", "services.cli", "router"]
    for ep in listen:
        args += ["--listen", ep]
    if certs is not None:
        args += ["--certs", certs]
        if acl is not None:
            args += ["--acl", str(acl)]
    # the launch checked exposure already (it holds --insecure); do not refuse twice
    args.append("--insecure")
    # a restarted router would not bring the run back: every session's state (subscriptions,
    # liveliness tokens, the services' view of the clock) goes with the old one
    child = sup.start(
        ROUTER,
        args,
        never_because="the router is never restarted: the run's sessions go with it",
        spawned=True,  # up while the fork server imports what the services need
    )
    deadline = time.monotonic() + timeout_s
    while READY_LINE not in child.tail(50):
        code = child.proc.poll()
        if code is not None:
            raise RuntimeError(
                f"the Zenoh router {how_it_ended(code)} before listening on "
                f"{', '.join(listen)}:\n{child.tail().rstrip()}"
            )
        if cancelled():
            raise Interrupted("interrupted while the router was starting")
        if time.monotonic() > deadline:
            raise TimeoutError(
                f"the Zenoh router did not listen on {', '.join(listen)} within {timeout_s} s"
            )
        time.sleep(0.02)  # polling a file; the router is a separate process
    return connectable(listen[0])
