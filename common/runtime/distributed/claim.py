"""One process per role per run: a service, or a run's clock, claims its role before it joins.

A claim is a liveliness token `tidelink/<run>/<vehicle>/claim/<role>/<id>`, the id the
claimant's wall-clock start (hex nanoseconds, so ids sort by time) and its Zenoh session id.
A process declares its claim, then asks for every claim of its role: an earlier one means the
role is taken, and it withdraws and is refused (RoleTaken), before it has subscribed or
published anything. Two that claim at the same moment see each other and the later one steps
aside, so a role never has two holders. An earlier claim that is on its way out (a restarted
service's predecessor; a host cut off holds its tokens up to its Zenoh lease) is waited for,
up to `wait_s`.

The run's clock watches every claim (ClaimWatch): a second claimant of a role raises an alarm
in the launch even though it is refused at once.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from common.bus import Bus, Keys

POLL_S = 0.1  # how often a claimant looks whether an earlier claim has gone
CLAIM_WAIT_S = 3.0  # how long a claimant waits for an earlier claim of its role to go


class RoleTaken(RuntimeError):
    """Another process holds this role in this run."""


def claim_id(bus: Bus) -> str:
    """This process's claim id: its wall-clock start and its session id."""
    return f"{time.time_ns():016x}-{bus.session.info.zid()}"


def started_s(ident: str) -> float:
    """The Unix time a claim id says its claimant claimed at."""
    try:
        return int(ident.split("-", 1)[0], 16) / 1e9
    except ValueError:
        return 0.0


def claim(bus: Bus, keys: Keys, role: str, *, wait_s: float = CLAIM_WAIT_S) -> str:
    """Claim `role` in the run of `keys` for as long as `bus` is open; returns the claim id.
    RoleTaken (naming the holder) when an earlier claim is still there after `wait_s`."""
    mine = claim_id(bus)
    token = bus.session.liveliness().declare_token(keys.claim(role, mine))
    deadline = time.monotonic() + wait_s
    while True:
        earlier = sorted(i for i in _claims(bus, keys, role) if i < mine)
        if not earlier:
            bus._keep(token)  # withdrawn with the bus, as every declaration
            return mine
        if time.monotonic() >= deadline:
            token.undeclare()
            since = time.strftime("%H:%M:%S", time.localtime(started_s(earlier[0])))
            raise RoleTaken(
                f"{role!r} is already in run {keys.run}/{keys.vehicle} (claimed at {since} by "
                f"session {earlier[0].split('-', 1)[-1]}): refused, one {role} per run "
                "(a process that has gone keeps its claim up to its Zenoh lease, 10 s)"
            )
        time.sleep(POLL_S)  # waiting for an earlier claimant to leave, not for a result


def _claims(bus: Bus, keys: Keys, role: str) -> list[str]:
    out = []
    for key in bus.alive_now(keys.claims(role), timeout_s=1.0):
        try:
            out.append(Keys.parse_claim(key)[3])
        except ValueError:
            continue
    return out


@dataclass
class ClaimWatch:
    """The claims of a run's roles as they come and go (liveliness events on Keys.all_claims);
    `seen` returns an alarm when a role has two claimants at once."""

    holders: dict[str, set[str]] = field(default_factory=dict)

    def seen(self, key: str, alive: bool) -> str | None:
        try:
            _, _, role, ident = Keys.parse_claim(key)
        except ValueError:
            return None
        held = self.holders.setdefault(role, set())
        if not alive:
            held.discard(ident)
            return None
        held.add(ident)
        if len(held) < 2:
            return None
        first, *later = sorted(held)
        return (
            f"ALARM: a second {role!r} tried to join the run (session {later[-1].split('-')[-1]}); "
            f"the {role} that joined first keeps the role, the other is refused"
        )
