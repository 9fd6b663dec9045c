"""Zenoh session settings of a process: mode, endpoints, scouting."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from common.config.errors import ConfigValueError


@dataclass(frozen=True, kw_only=True)
class BusConfig:
    """Zenoh session settings (in a scenario: where a lockstep run's router listens)."""

    mode: Literal["peer", "client", "router"] = "peer"
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    # Off by default: multicast leaves loopback and lets unrelated runs find each other.
    multicast_scouting: bool = False

    def __post_init__(self) -> None:
        for name in ("listen", "connect"):
            for i, ep in enumerate(getattr(self, name)):
                proto, sep, rest = ep.partition("/")
                if (
                    not sep
                    or not rest
                    or proto not in ("tcp", "udp", "ws", "unixsock-stream", "tls", "quic")
                ):
                    raise ConfigValueError(
                        (name, i), f"{ep!r} is not a Zenoh endpoint like tcp/127.0.0.1:7447"
                    )
        if self.mode == "client" and not self.connect:
            raise ConfigValueError(
                "connect", "a client must connect to at least one router endpoint"
            )
