"""Zenoh session settings of a process: mode, endpoints, scouting, transport security."""

from __future__ import annotations

import dataclasses
import ipaddress
from dataclasses import dataclass
from typing import Literal

from common.config.errors import ConfigValueError

PROTOCOLS = ("tcp", "udp", "ws", "unixsock-stream", "tls", "quic")
DEFAULT_CONNECT = "tcp/127.0.0.1:7447"  # Zenoh's own default port, on this machine


@dataclass(frozen=True, kw_only=True)
class BusConfig:
    """Zenoh session settings (in a scenario: where a lockstep run's router listens, and
    whether the run's bus is secured)."""

    mode: Literal["peer", "client", "router"] = "peer"
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    # Off by default: multicast leaves loopback and lets unrelated runs find each other.
    multicast_scouting: bool = False
    # "mtls": every endpoint is tls/ (tcp/ ones are served as tls/ on the same address) and
    # every process presents a certificate of the run's CA; docs/security.md
    security: Literal["none", "mtls"] = "none"
    # the directory `tidelink certs` wrote (ca.pem, <identity>.pem/.key); needed for "mtls"
    certs: str = ""
    # how long a silent peer (a host cut off, a frozen process) keeps its session, and so its
    # liveliness tokens: Zenoh's lease (it sends keep-alives 4 times a lease)
    lease_s: float = 10.0

    def __post_init__(self) -> None:
        for name in ("listen", "connect"):
            for i, ep in enumerate(getattr(self, name)):
                proto, sep, rest = ep.partition("/")
                if not sep or not rest or proto not in PROTOCOLS:
                    raise ConfigValueError(
                        (name, i), f"{ep!r} is not a Zenoh endpoint like tcp/127.0.0.1:7447"
                    )
                if proto == "tls" and self.security != "mtls":
                    raise ConfigValueError(
                        (name, i),
                        f'{ep!r} is a TLS endpoint: it needs security = "mtls" and a certs '
                        "directory (--certs DIR)",
                    )
        if not 0.1 <= self.lease_s <= 3600.0:
            raise ConfigValueError("lease_s", f"{self.lease_s!r} s: must be 0.1 to 3600 s")
        if self.mode == "client" and not self.connect:
            raise ConfigValueError(
                "connect", "a client must connect to at least one router endpoint"
            )
        if self.security == "mtls" and not self.certs:
            raise ConfigValueError(
                "certs",
                'security = "mtls" needs the certificates directory (certs = "DIR" or '
                "--certs DIR; `tidelink certs DIR` creates one)",
            )

    @property
    def secured(self) -> bool:
        return self.security == "mtls"

    def endpoint(self, ep: str) -> str:
        """The endpoint as the session uses it: under mTLS a tcp/ endpoint is tls/ (same
        address), so one --listen/--connect spelling works with and without certificates."""
        proto, _, rest = ep.partition("/")
        return f"tls/{rest}" if self.secured and proto == "tcp" else ep

    def client_of(self, connect: str) -> BusConfig:
        """A client session of the router at `connect`, with this config's security."""
        return dataclasses.replace(self, mode="client", listen=(), connect=(connect,))

    def router_on(self, listen: tuple[str, ...]) -> BusConfig:
        """A router session listening on `listen`, with this config's security."""
        return dataclasses.replace(self, mode="router", listen=listen, connect=())


def is_loopback(endpoint: str) -> bool:
    """Whether an endpoint's address stays on this machine (127.0.0.0/8, ::1, localhost;
    unix sockets). 0.0.0.0 and [::] listen on every interface: not loopback."""
    proto, _, addr = endpoint.partition("/")
    if proto == "unixsock-stream":
        return True
    host = addr.split("#", 1)[0].rpartition(":")[0].strip("[]")
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a host name: it may resolve to anything


def tcp_address(endpoint: str) -> tuple[str, int] | None:
    """(host, port) of a tcp/ or tls/ endpoint, its #options left out; None for any other."""
    proto, _, addr = endpoint.partition("/")
    host, _, port = addr.split("#", 1)[0].rpartition(":")
    if proto not in ("tcp", "tls") or not port.isdigit():
        return None
    return host.strip("[]"), int(port)


def client_config(connect: str, certs: str | None) -> BusConfig:
    """A client of the router at `connect`: under mTLS when a certs directory is given."""
    return BusConfig(
        mode="client",
        connect=(connect,),
        security="mtls" if certs else "none",
        certs=certs or "",
    )


@dataclass(frozen=True, kw_only=True)
class WatchTarget:
    """What a watching tool (monitor, Foxglove bridge) joins: the run's router, as a client
    under mTLS when `certs` is given, and which run and vehicle to watch (None: any)."""

    connect: str = DEFAULT_CONNECT
    certs: str | None = None  # mTLS with these certificates (docs/security.md)
    identity: str = "monitor"  # whose certificate to present
    run: str | None = None
    vehicle: str | None = None
