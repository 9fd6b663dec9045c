"""Network namespaces joined by veth pairs, so tests cross real interfaces on one machine.

Everything is created inside namespaces named tl<tag>…, with addresses that exist only
there, and deleted at the end (deleting a namespace deletes its veth ends and their
qdiscs). Needs root and iproute2 (`ip`, and `tc` for shaping); `lab_or_skip` skips the test
with the reason where a namespace cannot be created.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import pytest


def ip(*args: str) -> str:
    """`ip ARGS`; RuntimeError with ip's message when it fails."""
    return _run("ip", *args)


def tc(ns: str, *args: str) -> str:
    """`tc -n NS ARGS` (traffic control inside a namespace)."""
    return _run("tc", "-n", ns, *args)


def _run(*cmd: str) -> str:
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=15, check=False)
    if res.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: {res.stderr.strip()}")
    return res.stdout


@dataclass(frozen=True)
class Veth:
    """One veth pair: device `dev_a` (address `ip_a`) in `ns_a`, `dev_b` (`ip_b`) in `ns_b`."""

    ns_a: str
    dev_a: str
    ip_a: str
    ns_b: str
    dev_b: str
    ip_b: str


@dataclass(frozen=True)
class Tbf:
    """A token-bucket shaper as `tc qdisc show` reports it, with its counters."""

    rate: str
    burst: str
    latency: str
    sent_bytes: int
    dropped: int
    overlimits: int


class NetnsLab:
    """The namespaces and veth links of one test; `delete` removes all of them."""

    def __init__(self, tag: str) -> None:
        self.tag = tag
        self.created: list[str] = []

    def namespace(self, suffix: str) -> str:
        """Create namespace tl<tag><suffix> with its loopback up; returns its name."""
        ns = f"tl{self.tag}{suffix}"
        if ns not in self.created:
            ip("netns", "add", ns)
            self.created.append(ns)
        ip("-n", ns, "link", "set", "lo", "up")
        return ns

    def veth(self, ns_a: str, ns_b: str, net: str, suffix: str) -> Veth:
        """A veth pair between two namespaces: <net>.1/30 on the a side, <net>.2/30 on the b
        side (net: three octets, e.g. "10.201.1"); devices tl<tag><suffix>a and ...b."""
        dev_a, dev_b = f"tl{self.tag}{suffix}a", f"tl{self.tag}{suffix}b"
        ip_a, ip_b = f"{net}.1", f"{net}.2"
        # both ends are created directly inside their namespaces
        ip(
            "link",
            "add",
            dev_a,
            "netns",
            ns_a,
            "type",
            "veth",
            "peer",
            "name",
            dev_b,
            "netns",
            ns_b,
        )
        ip("-n", ns_a, "addr", "add", f"{ip_a}/30", "dev", dev_a)
        ip("-n", ns_b, "addr", "add", f"{ip_b}/30", "dev", dev_b)
        ip("-n", ns_a, "link", "set", dev_a, "up")
        ip("-n", ns_b, "link", "set", dev_b, "up")
        return Veth(ns_a, dev_a, ip_a, ns_b, dev_b, ip_b)

    def delete(self) -> None:
        for ns in reversed(self.created):  # deleting a namespace deletes its veth ends
            subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=15, check=False)


def link_bytes(ns: str, dev: str) -> tuple[int, int]:
    """(tx, rx) bytes a device has carried so far."""
    (info,) = json.loads(ip("-n", ns, "-j", "-s", "link", "show", dev))
    stats = info["stats64"]
    return int(stats["tx"]["bytes"]), int(stats["rx"]["bytes"])


def shape(ns: str, dev: str, rate: str, burst: str, latency: str) -> Tbf:
    """Shape a device's egress with a token bucket (`tc qdisc add ... root tbf`) and return it
    as tc reports it back (so a test states what is in force, not what it asked for)."""
    tc(
        ns,
        "qdisc",
        "add",
        "dev",
        dev,
        "root",
        "tbf",
        "rate",
        rate,
        "burst",
        burst,
        "latency",
        latency,
    )
    return tbf(ns, dev)


_TBF = re.compile(r"qdisc tbf \S+ root .*?rate (\S+) burst (\S+) lat (\S+)")
_SENT = re.compile(r"Sent (\d+) bytes \d+ pkt \(dropped (\d+), overlimits (\d+)")


def tbf(ns: str, dev: str) -> Tbf:
    """The tbf qdisc on a device and its counters; RuntimeError if there is none."""
    out = tc(ns, "-s", "qdisc", "show", "dev", dev)
    head, sent = _TBF.search(out), _SENT.search(out)
    if head is None or sent is None:
        raise RuntimeError(f"no tbf qdisc on {ns}/{dev}:\n{out}")
    return Tbf(
        rate=head[1],
        burst=head[2],
        latency=head[3],
        sent_bytes=int(sent[1]),
        dropped=int(sent[2]),
        overlimits=int(sent[3]),
    )


@contextmanager
def lab_or_skip(*, need_tc: bool = False) -> Iterator[NetnsLab]:
    """A NetnsLab for one test (tagged by pid), or pytest.skip with the reason when this machine
    cannot create namespaces (no iproute2, not root) or shape links (no tc, no tbf)."""
    for tool in ("ip", "tc") if need_tc else ("ip",):
        if shutil.which(tool) is None:
            pytest.skip(f"no `{tool}` command (iproute2): cannot build the test's hosts")
    tag = f"{os.getpid() % 0xFFFF:04x}"
    probe = NetnsLab(tag)
    try:
        try:
            a = probe.namespace("px")
        except RuntimeError as exc:
            pytest.skip(f"cannot create a network namespace here (needs root): {exc}")
        if need_tc:
            link = probe.veth(a, probe.namespace("py"), "10.254.254", "p")
            try:
                shape(link.ns_a, link.dev_a, "64kbit", "4kb", "400ms")
            except RuntimeError as exc:
                pytest.skip(f"cannot shape a link with tc tbf here: {exc}")
    finally:
        probe.delete()
    lab = NetnsLab(tag)
    try:
        yield lab
    finally:
        lab.delete()
