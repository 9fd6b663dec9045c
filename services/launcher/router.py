"""Start the run's Zenoh router (`tidelink router`) as a supervised process and wait for it."""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from common.config.bus import DEFAULT_CONNECT
from common.runtime.processes.children import connectable, free_port, how_it_ended, port_free
from common.runtime.processes.policy import RestartPolicy
from common.runtime.processes.signals import Interrupted
from common.runtime.processes.supervisor import Supervisor

ROUTER = "router"
READY_LINE = "zenoh router listening on"  # printed by `tidelink router` once it listens
NEVER_RESTARTED = "the router is never restarted without --restart router=on-failure"
ADDRESS_IN_USE = "Address already in use"  # in Zenoh's error when a listener cannot bind


class PortTaken(RuntimeError):
    """The router could not listen: its port was taken (by another launch, say)."""


@dataclass(frozen=True)
class Listening:
    """Where the run's router listens: the endpoint local processes dial, and why it is not
    the default endpoint (None when it is the default, or the one asked for)."""

    endpoint: str
    instead_of_default: str | None = None


def start_router(
    sup: Supervisor,
    listen: tuple[str, ...],
    *,
    timeout_s: float = 30.0,
    cancelled: Callable[[], bool] = lambda: False,
    certs: str | None = None,
    acl: Path | None = None,
    policy: RestartPolicy | None = None,
) -> Listening:
    """Start the router listening on `listen` and wait until it says it listens. Without
    `listen`: on DEFAULT_CONNECT, where the watchers (monitor, foxglove, record) look by
    default, when that port is free; else (or when another launch takes it first) on a free
    loopback port, and Listening says why. With `certs` it listens on TLS only, as the router
    identity, enforcing the access control in the `acl` file. `policy` (`--restart
    router=on-failure`): restarted on the same endpoints, the run's sessions reconnect to it
    (clients retry every second) and declare everything again."""
    go = functools.partial(
        _start, sup, timeout_s=timeout_s, cancelled=cancelled, certs=certs, acl=acl, policy=policy
    )
    if listen:
        return Listening(go(listen))
    taken = f"{DEFAULT_CONNECT} is taken"
    if port_free(DEFAULT_CONNECT):
        try:
            return Listening(go((DEFAULT_CONNECT,)))
        except PortTaken:  # taken between our look and the router's bind
            sup.forget(ROUTER)
            taken = f"{DEFAULT_CONNECT} was taken as the router started"
    return Listening(go((f"tcp/127.0.0.1:{free_port()}",)), instead_of_default=taken)


def _start(
    sup: Supervisor,
    listen: tuple[str, ...],
    *,
    timeout_s: float,
    cancelled: Callable[[], bool],
    certs: str | None,
    acl: Path | None,
    policy: RestartPolicy | None,
) -> str:
    """Start `tidelink router` on `listen`, wait for its ready line; the endpoint to dial."""
    args = ["-m", "services.cli", "router"]
    for ep in listen:
        args += ["--listen", ep]
    if certs is not None:
        args += ["--certs", certs]
        if acl is not None:
            args += ["--acl", str(acl)]
    # the launch checked exposure already (it holds --insecure); do not refuse twice
    args.append("--insecure")
    # restarted, only by its own policy: every client reconnects within a second and declares
    # its subscriptions, queryables and tokens again; what was on its way is lost
    child = sup.start(
        ROUTER,
        args,
        policy,
        never_because="" if policy is not None else NEVER_RESTARTED,
        spawned=True,  # up while the fork server imports what the services need
    )
    deadline = time.monotonic() + timeout_s
    while READY_LINE not in child.tail(50):
        code = child.proc.poll()
        if code is not None:
            tail = child.tail().rstrip()
            if ADDRESS_IN_USE in tail:
                raise PortTaken(f"{', '.join(listen)} is taken:\n{tail}")
            raise RuntimeError(
                f"the Zenoh router {how_it_ended(code)} before listening on "
                f"{', '.join(listen)}:\n{tail}"
            )
        if cancelled():
            raise Interrupted("interrupted while the router was starting")
        if time.monotonic() > deadline:
            raise TimeoutError(
                f"the Zenoh router did not listen on {', '.join(listen)} within {timeout_s} s"
            )
        time.sleep(0.02)  # polling a file; the router is a separate process
    return connectable(listen[0])
