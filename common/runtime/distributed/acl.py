"""Least-privilege Zenoh access control for a run, generated from its declared dataflow.

Each identity (a certificate's common name) gets exactly what its code does on the bus
(docs/security.md):
- a service puts its own output streams, its stats and its lockstep acks, subscribes to its
  inputs and to the ticks addressed to it (a lockstep tick carries its inputs), declares only
  its own liveliness token and claim to its role (and sees the other claims of it), and may
  ask the tap for its own newest frames (a restarted vehicle resumes from them);
- the launcher (the clock) puts ticks and the watch copies, hears every stream, serves the
  run's dataflow, latest frames and scenario, owns the clock's token and claim, and sees
  every claim;
- a monitor sees every run on the router through its watch tap (subscribes to the watch
  copies and liveliness, queries latest frames, scenario and dataflow) and puts nothing;
- the router identity only routes.
Everything else is denied (default_permission "deny"). Nothing here is hand-written per
stream: add an output to a service's declaration and its rules follow.

How a grant becomes Zenoh rules (flows are seen from the router: ingress is what a client
sends it, egress what it sends a client; measured in tests/test_acl_live.py):
- put K:        put ingress; and declare_subscriber egress on all of tidelink/**: a client
                publisher sends only once it has heard of a matching subscriber, and the
                subscriptions it must hear of are declared on wider keys than K (the clock's
                .../*/*, a monitor's tidelink/*/*/watch/**). Seeing that a subscriber exists
                is all this grants.
- subscribe K:  declare_subscriber ingress, put egress. The *declared* key expression must lie
                inside an allowed one (ZENOH.md), so grants use the keys the code declares.
- serve K:      declare_queryable and reply ingress, query egress
- query K:      query ingress, reply egress; declare_queryable egress on tidelink/** (as put)
- token K:      liveliness_token ingress
- watch K:      declare_liveliness_subscriber and liveliness_query ingress,
                liveliness_token egress
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Literal, TypedDict

from common.bus import CLOCK, Keys
from common.runtime.model.dataflow import Dataflow
from common.runtime.model.host import STATS_STREAM

LAUNCHER = "launcher"  # the clock's identity: `tidelink launch` and the runtimes' driver
MONITOR = "monitor"  # tools that watch: monitor, foxglove, record, graph
ROUTER = "router"  # the router process: routes, and nothing else

# (message, flow) pairs each kind of grant needs, see the module docstring
_FLOWS: dict[str, tuple[tuple[str, str], ...]] = {
    "put": (("put", "ingress"),),
    "subscribe": (("declare_subscriber", "ingress"), ("put", "egress")),
    "serve": (("declare_queryable", "ingress"), ("reply", "ingress"), ("query", "egress")),
    "query": (("query", "ingress"), ("reply", "egress")),
    "token": (("liveliness_token", "ingress"),),
    "watch": (
        ("declare_liveliness_subscriber", "ingress"),
        ("liveliness_query", "ingress"),
        ("liveliness_token", "egress"),
    ),
}
# what a publisher or querier must hear of, whatever its keys (see the module docstring)
_DISCOVERY: dict[str, tuple[str, str]] = {
    "put": ("declare_subscriber", "egress"),
    "query": ("declare_queryable", "egress"),
}
ALL_RUNS = "tidelink/**"


@dataclass(frozen=True)
class Grants:
    """What one identity may do on the bus: key expressions per kind of operation."""

    put: tuple[str, ...] = ()
    subscribe: tuple[str, ...] = ()
    serve: tuple[str, ...] = ()
    query: tuple[str, ...] = ()
    token: tuple[str, ...] = ()
    watch: tuple[str, ...] = ()

    def items(self) -> list[tuple[str, tuple[str, ...]]]:
        """(kind, key expressions) for every kind granted at all."""
        return [(f.name, getattr(self, f.name)) for f in fields(self) if getattr(self, f.name)]


def run_grants(flow: Dataflow, keys: Keys) -> dict[str, Grants]:
    """Every identity of a run and what it may do, from the mission's declared dataflow."""
    out: dict[str, Grants] = {}
    for name, svc in flow.services.items():
        streams = [o.stream for o in svc.outputs] + [STATS_STREAM]
        out[name] = Grants(
            put=(*(keys.stream(name, s) for s in streams), keys.ack(name)),
            subscribe=(
                *(keys.stream(i.source, i.stream) for i in svc.inputs),
                keys.ticks_for(name),
            ),
            # its token, and its claim to its role (claim.py): it asks for the others' claims
            token=(keys.alive(name), keys.claims(name)),
            watch=(keys.alive(CLOCK), keys.claims(name)),
            # its own newest frames, kept by the launcher's tap: a restarted core resumes
            # from them (service_process.resume_from_tap)
            query=(keys.latest(name, "*"),),
        )
    out[LAUNCHER] = Grants(
        put=(f"{keys.root}/{CLOCK}/tick/**", keys.all_watch),
        # the probe: a replay (this identity) checks that its puts get through (probe.py)
        subscribe=(keys.all_streams, keys.all_acks, keys.probe),
        serve=(keys.dataflow, keys.all_latest, keys.scenario),
        token=(keys.alive(CLOCK), keys.claims(CLOCK)),
        watch=(keys.all_alive, keys.all_claims),
    )
    # any run on this router (a watcher need not name the run), but through the watch tap
    # only: a monitor that subscribed to the BLOCK control streams and stopped reading could
    # stall the run (docs/monitoring.md); the tap carries every stream anyway
    anywhere = Keys.matching()
    out[MONITOR] = Grants(
        subscribe=(anywhere.all_watch,),
        query=(anywhere.all_latest, anywhere.scenario, anywhere.dataflow),
        watch=(anywhere.all_alive,),
    )
    out[ROUTER] = Grants()
    return out


class AclRule(TypedDict):
    """A rule of Zenoh's access_control: these messages in this flow, on these keys."""

    id: str
    messages: list[str]
    flows: list[str]  # "ingress" or "egress", seen from the router
    permission: Literal["allow", "deny"]
    key_exprs: list[str]


class AclSubject(TypedDict):
    """A subject of Zenoh's access_control: whoever presents a certificate of this name."""

    id: str
    cert_common_names: list[str]


class AclPolicy(TypedDict):
    """A policy of Zenoh's access_control: these rules apply to these subjects."""

    rules: list[str]
    subjects: list[str]


class AccessControl(TypedDict):
    """Zenoh's `access_control` config object, as access_control() writes it."""

    enabled: bool
    default_permission: Literal["allow", "deny"]
    rules: list[AclRule]
    subjects: list[AclSubject]
    policies: list[AclPolicy]


def access_control(grants: dict[str, Grants]) -> AccessControl:
    """Zenoh's `access_control` config object for these grants: one subject per identity
    (its certificate's common name), one rule per (identity, message, flow), default deny."""
    rules: list[AclRule] = []
    subjects: list[AclSubject] = []
    policies: list[AclPolicy] = []
    for identity, g in sorted(grants.items()):
        subjects.append({"id": identity, "cert_common_names": [identity]})
        by_message: dict[tuple[str, str], list[str]] = {}
        for kind, key_exprs in g.items():
            for message, flow in _FLOWS[kind]:
                merged = by_message.setdefault((message, flow), [])
                merged.extend(k for k in key_exprs if k not in merged)
            if kind in _DISCOVERY:
                by_message[_DISCOVERY[kind]] = [ALL_RUNS]
        ids = []
        for (message, flow), allowed in sorted(by_message.items()):
            rule_id = f"{identity}/{message}/{flow}"
            rules.append(
                {
                    "id": rule_id,
                    "messages": [message],
                    "flows": [flow],
                    "permission": "allow",
                    "key_exprs": allowed,
                }
            )
            ids.append(rule_id)
        if ids:
            policies.append({"rules": ids, "subjects": [identity]})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def describe(grants: dict[str, Grants]) -> str:
    """The grants as a table for review (`tidelink acl SCENARIO`)."""
    lines = []
    for identity, g in sorted(grants.items()):
        lines.append(f"{identity}:")
        if not g.items():
            lines.append("  (nothing: routes only)" if identity == ROUTER else "  (nothing)")
        for kind, key_exprs in g.items():
            for k in key_exprs:
                lines.append(f"  {kind:<10} {k}")
    return "\n".join(lines)
