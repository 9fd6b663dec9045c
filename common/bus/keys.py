"""Key expressions of a run: tidelink/<run>/<vehicle>/<service>/<stream> and liveliness."""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property

_ID = re.compile(r"^[A-Za-z0-9_\-]+$")
# a service name may be a fleet vehicle's ("auv2.planner", common/runtime/model/dataflow.py)
_SERVICE = re.compile(r"^[A-Za-z0-9_\-]+(\.[A-Za-z0-9_\-]+)?$")
CLOCK = "runtime"  # the clock's service name in keys: .../runtime/tick/..., .../runtime/ack/...
WATCH = "watch"  # .../watch/<service>/<stream>: the monitoring copy of every stream
END = "end"  # .../watch/runtime/end: the clock's RunEnd
PROBE = "probe"  # .../watch/runtime/probe: a replay's check that its puts get through
LATEST = "latest"  # .../latest/<service>/<stream>: queryable newest frame of every stream
ANY = "*"  # a run or vehicle of Keys.matching left open
CLAIM = "claim"  # .../claim/<role>/<id>: one process per role (common/runtime/distributed/claim.py)


@dataclass(frozen=True)
class Keys:
    """Builds the key expressions of one run and vehicle, so no code formats keys by hand.

    Keys.matching(run, vehicle) stands for any run or vehicle left None ("*"): its all_alive,
    all_watch, all_latest, scenario and dataflow are selectors over every run that is on.
    """

    run: str
    vehicle: str

    def __post_init__(self) -> None:
        for what, v in (("run", self.run), ("vehicle", self.vehicle)):
            if not (_ID.match(v) or v == ANY):
                raise ValueError(f"{what}: {v!r} must be letters, digits, '_' or '-'")

    @classmethod
    def matching(cls, run: str | None = None, vehicle: str | None = None) -> Keys:
        """The keys of one run and vehicle, or of any (None: a wildcard), for selectors."""
        return cls(run or ANY, vehicle or ANY)

    @cached_property
    def root(self) -> str:
        """tidelink/<run>/<vehicle>: built once, as a coordinator tests every ack's key."""
        return f"tidelink/{self.run}/{self.vehicle}"

    @cached_property
    def _clock_prefixes(self) -> tuple[str, str]:
        """What every tick key and every ack key of this run start with (is_tick, acked_by)."""
        clock = f"{self.root}/{CLOCK}"
        return f"{clock}/tick/", f"{clock}/ack/"

    def stream(self, service: str, stream: str) -> str:
        """The key of one service's output stream, e.g. tidelink/demo/auv1/sensor/nav."""
        return f"{self.root}/{service}/{stream}"

    def tick(self, recipients: Iterable[str]) -> str:
        """The key of a clock tick for these services: .../runtime/tick/<a>/<b>/... (sorted).

        Naming the recipients in the key lets Zenoh deliver a tick only to the services it
        is for: on a lockstep run most ticks wake two or three services, not all of them.
        """
        names = sorted(recipients)
        bad = [n for n in names if not _SERVICE.match(n)]
        if not names or bad:
            raise ValueError(
                f"a tick needs recipients named by letters, digits, '_' or '-' (and one '.' "
                f"after a fleet vehicle's id): {bad}"
            )
        return f"{self.root}/{CLOCK}/tick/{'/'.join(names)}"

    def ticks_for(self, service: str) -> str:
        """The key expression of every tick whose recipients include `service`."""
        return f"{self.root}/{CLOCK}/tick/**/{service}/**"

    def is_tick(self, key: str) -> bool:
        """Is `key` one of this run's clock tick keys (whatever its recipients)?"""
        return key.startswith(self._clock_prefixes[0])

    def ack(self, service: str) -> str:
        """The key of a service's lockstep acknowledgements: .../runtime/ack/<service> (the
        coordinator hears them all, a service those of the services it reads)."""
        return f"{self.root}/{CLOCK}/ack/{service}"

    @property
    def all_acks(self) -> str:
        return self.ack("*")

    def acked_by(self, key: str) -> str | None:
        """The service whose acknowledgement key `key` is, or None for any other key."""
        prefix = self._clock_prefixes[1]
        return key[len(prefix) :] if key.startswith(prefix) else None

    def alive(self, service: str) -> str:
        """The liveliness token key of a service."""
        return f"{self.root}/alive/{service}"

    @property
    def all_alive(self) -> str:
        return self.alive("*")

    def claim(self, role: str, ident: str) -> str:
        """The liveliness key of one process's claim to a role (a service, or the clock)."""
        return f"{self.root}/{CLAIM}/{role}/{ident}"

    def claims(self, role: str) -> str:
        """Every claim to `role`."""
        return self.claim(role, "*")

    @property
    def all_claims(self) -> str:
        return f"{self.root}/{CLAIM}/*/*"

    def is_claim(self, key: str) -> bool:
        return key.startswith(f"{self.root}/{CLAIM}/")

    @staticmethod
    def parse_claim(key: str) -> tuple[str, str, str, str]:
        """(run, vehicle, role, claim id) of a claim key; ValueError for any other key."""
        parts = key.split("/")
        if len(parts) != 6 or parts[0] != "tidelink" or parts[3] != CLAIM:
            raise ValueError(f"{key!r} is not a tidelink claim key")
        return parts[1], parts[2], parts[4], parts[5]

    @property
    def all_streams(self) -> str:
        """Every <service>/<stream> key of the run: data and stats, but no clock ticks or acks
        (their keys have more chunks), so a clock that records a run does not hear its own."""
        return f"{self.root}/*/*"

    @property
    def dataflow(self) -> str:
        """The key a running mission answers queries on with its declared dataflow."""
        return f"{self.root}/dataflow"

    # -- what tools outside the run see (common/bus/tap.py, docs/monitoring.md) -------------
    def watch(self, service: str, stream: str) -> str:
        """The monitoring copy of a stream, republished by the run's watch tap (DROP)."""
        return f"{self.root}/{WATCH}/{service}/{stream}"

    @property
    def all_watch(self) -> str:
        return f"{self.root}/{WATCH}/**"

    def latest(self, service: str, stream: str) -> str:
        """The queryable answering with a stream's newest frame (late joiners, thin links)."""
        return f"{self.root}/{LATEST}/{service}/{stream}"

    @property
    def all_latest(self) -> str:
        return f"{self.root}/{LATEST}/**"

    @property
    def scenario(self) -> str:
        """The queryable answering with the run's scenario (its static world included)."""
        return f"{self.root}/scenario"

    @property
    def probe(self) -> str:
        """Where a replay checks that the router lets its puts through (common/bus/probe.py);
        watchers ignore it."""
        return self.watch(CLOCK, PROBE)

    @property
    def end(self) -> str:
        """Where the clock announces the run's end (JSON: reason, t_end_s, ticks)."""
        return self.watch(CLOCK, END)

    @staticmethod
    def parse_watch(key: str) -> tuple[str, str, str, str]:
        """(run, vehicle, service, stream) of a watch or latest key; ValueError otherwise."""
        parts = key.split("/")
        if len(parts) != 6 or parts[0] != "tidelink" or parts[3] not in (WATCH, LATEST):
            raise ValueError(f"{key!r} is not a tidelink watch or latest key")
        return parts[1], parts[2], parts[4], parts[5]

    @staticmethod
    def parse_alive(key: str) -> tuple[str, str, str]:
        """(run, vehicle, service) of a liveliness key; ValueError for any other key."""
        parts = key.split("/")
        if len(parts) != 5 or parts[0] != "tidelink" or parts[3] != "alive":
            raise ValueError(f"{key!r} is not a tidelink liveliness key")
        return parts[1], parts[2], parts[4]

    @property
    def everything(self) -> str:
        return f"{self.root}/**"

    def split(self, key: str) -> tuple[str, str]:
        """(service, stream) of a stream key of this run; ValueError for any other key."""
        prefix = self.root + "/"
        if not key.startswith(prefix):
            raise ValueError(f"{key!r} is not a key of run {self.run}/{self.vehicle}")
        service, sep, stream = key[len(prefix) :].partition("/")
        if not sep or "/" in stream:
            raise ValueError(f"{key!r} is not a <service>/<stream> key")
        return service, stream
