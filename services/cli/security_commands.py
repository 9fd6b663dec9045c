"""The security sub-commands: certs and acl."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from services.cli.flags import Subparsers, command, scenario_args


def _csv(text: str) -> list[str]:
    """'a, b,,c' -> ['a', 'b', 'c']: a comma-separated list, spaces and empty items ignored."""
    return [item.strip() for item in text.split(",") if item.strip()]


def cmd_certs(a: argparse.Namespace) -> int:
    """create a CA and a key + certificate per identity for mutual TLS

    Create (or reuse) a certificate authority in DIR and a key + certificate per identity, for
    Zenoh's mutual TLS. An existing CA is never overwritten; existing identities are kept unless
    --renew. Files are mode 0600, DIR 0700 when created."""
    # imported here: cryptography is slow to import, which the other commands need not pay
    from common.bus.certs import DEFAULT_IDENTITIES, create_certs

    names = DEFAULT_IDENTITIES if a.names is None else _csv(a.names)
    hosts = None if a.hosts is None else _csv(a.hosts)
    for path, what in create_certs(a.dir, names, days=a.days, hosts=hosts, renew=a.renew):
        print(f"{what:<9}  {path}")
    print(
        f"give --certs {a.dir} to launch/service/router/monitor/... "
        "(each process loads the identity it runs as)"
    )
    return 0


def cmd_acl(a: argparse.Namespace) -> int:
    """print the access control a secured run enforces (generated from its dataflow)"""
    from common.config.scenario import load_scenario
    from common.runtime.distributed.acl import access_control, describe, run_grants
    from common.runtime.distributed.bringup import run_keys
    from common.runtime.model.mission import load_mission

    scenario, _ = load_scenario(a.scenario, a.overrides, a.seed)
    grants = run_grants(load_mission(scenario).dataflow, run_keys(scenario))
    if a.json:
        print(json.dumps(access_control(grants), indent=2))
    else:
        print(describe(grants))
        print(
            "(everything else is denied; --json prints the Zenoh access_control object "
            "for `tidelink router --acl FILE`)"
        )
    return 0


def register(sub: Subparsers) -> None:
    """Add certs and acl to the tidelink parser."""
    c = command(sub, "certs", cmd_certs)
    c.add_argument("dir", type=Path, metavar="DIR", help="the certificate directory")
    c.add_argument(
        "--names",
        default=None,
        metavar="A,B,...",
        help="identities to issue (default: every identity of a run: router, launcher, "
        "and each service and tool)",
    )
    c.add_argument(
        "--days", type=int, default=365, help="validity of the issued certificates (default 365)"
    )
    c.add_argument(
        "--hosts",
        default=None,
        metavar="H1,H2,...",
        help="names and addresses a listener is reached by, put in every certificate "
        "(default: localhost, 127.0.0.1, ::1 and this host's name)",
    )
    c.add_argument(
        "--renew", action="store_true", help="re-issue existing identities from the same CA"
    )

    acl = command(sub, "acl", cmd_acl)
    scenario_args(acl)
    acl.add_argument(
        "--json", action="store_true", help="the Zenoh access_control object, for --acl FILE"
    )
