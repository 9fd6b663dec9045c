"""A secured run, end to end with real processes over mutual TLS: a rogue client holding a
valid monitor certificate cannot steer or stop it, and still watches it; bad security input
is refused before any process starts (exit 2, naming the file)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from helpers.launch_proc import REPO, Tidelink, kill_recorded
from helpers.runs import inproc

from common.config.scenario import load_scenario
from common.runtime.processes.children import free_port

WAIT_S = 120.0
DEFAULT = str(REPO / "configs" / "default.toml")
SHORT = str(REPO / "configs" / "experiments" / "scenarios" / "short.toml")


def cli(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "services.cli", *args],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.mark.deterministic
@pytest.mark.slow
def test_a_rogue_with_a_monitor_certificate_changes_nothing(certs: Path, tmp_path: Path) -> None:
    """Lockstep under mTLS + access control, with a rogue putting commands (source
    "planner", fresh stamps, newer seqs) and stop ticks at 100 Hz and declaring the
    planner's token: the vehicle applies none of them (the trajectory is the plain inproc
    run's, bit for bit), the mission ends normally, and the rogue watched it all along, as
    did `tidelink monitor` with the same certificate."""
    plain = inproc(load_scenario(SHORT)[0]).metrics
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    out = tmp_path / "secured"
    common = ["--connect", endpoint, "--certs", str(certs)]
    try:
        with (
            Tidelink.python("-m", "helpers.rogue", *common, "--run", "short") as rogue,
            Tidelink("monitor", *common, "--json") as monitor,
            Tidelink(
                "launch",
                SHORT,
                "--runtime",
                "lockstep",
                "--listen",
                endpoint,
                "--certs",
                str(certs),
                "--out",
                str(out),
                "--json",
                "--no-plot",
            ) as launch,
        ):
            assert launch.wait(WAIT_S) == 0, launch.stderr
            assert rogue.wait(WAIT_S) == 0, rogue.stderr
            assert monitor.wait(WAIT_S) == 0, monitor.stderr
    finally:
        kill_recorded(out / "pids.json")
    secured = json.loads((out / "metrics.json").read_text())
    assert "mutual TLS" in launch.stderr
    assert secured["end_reason"] == "goal" and secured["reached_goal"] is True
    assert secured["trajectory_sha256"] == plain.trajectory_sha256
    assert secured["commands_applied"] == plain.commands_applied
    assert secured["commands_rejected"] == 0  # nothing of the rogue's even reached the vehicle
    report = json.loads(rogue.stdout.splitlines()[-1])
    assert rogue.stdout.splitlines()[0] == "connected"
    # it was on the bus during the run: it sent while watching frames, and saw the end
    assert report["sent_while_watching"] > 10 and report["watched"] > 100, report
    assert report["saw_end"] is True, report
    lines = [json.loads(s) for s in monitor.stdout.splitlines() if s.startswith("{")]
    assert any(x.get("event") == "end" for x in lines), monitor.stdout[-2000:]


def test_listening_beyond_loopback_needs_certs_or_insecure(tmp_path: Path) -> None:
    r = cli("router", "--listen", f"tcp/0.0.0.0:{free_port()}")
    assert r.returncode == 2
    assert "reachable from other machines" in r.stderr and "--certs" in r.stderr
    r = cli("launch", DEFAULT, "--listen", "tcp/0.0.0.0:7447", "--out", str(tmp_path / "x"))
    assert r.returncode == 2 and "--insecure" in r.stderr
    assert not (tmp_path / "x").exists()  # refused before anything started


def test_mtls_without_a_certs_directory_is_a_config_error() -> None:
    r = cli("check", DEFAULT, "--set", 'bus.security="mtls"')
    assert r.returncode == 2
    assert "bus.certs" in r.stderr and "tidelink certs" in r.stderr


def test_a_tls_endpoint_without_certs_is_a_config_error(tmp_path: Path) -> None:
    out = tmp_path / "run"
    r = cli("launch", DEFAULT, "--listen", "tls/127.0.0.1:7447", "--out", str(out))
    assert r.returncode == 2 and "TLS endpoint" in r.stderr and "--certs" in r.stderr
    assert not out.exists()
    r = cli("monitor", "--connect", "tls/127.0.0.1:7447", "--no-wait")
    assert r.returncode == 2 and "TLS endpoint" in r.stderr


def test_bad_certificate_files_exit_2_naming_the_file(certs: Path, tmp_path: Path) -> None:
    broken = tmp_path / "certs"
    shutil.copytree(certs, broken)
    (broken / "planner.key").unlink()
    out = tmp_path / "run"
    r = cli("launch", DEFAULT, "--certs", str(broken), "--out", str(out))
    assert r.returncode == 2, r.stderr
    assert str(broken / "planner.key") in r.stderr
    assert not (out / "logs").exists()  # no process started
    # a key that is not its certificate's
    shutil.copy(broken / "vehicle.key", broken / "planner.key")
    r = cli("service", "planner", DEFAULT, "--connect", "tcp/127.0.0.1:1", "--certs", str(broken))
    assert r.returncode == 2 and "planner" in r.stderr and "match" in r.stderr, r.stderr
    r = cli("monitor", "--certs", str(tmp_path / "nowhere"), "--no-wait")
    assert r.returncode == 2 and "nowhere" in r.stderr, r.stderr


def test_a_client_from_another_ca_is_refused_with_a_reason(certs: Path, other_certs: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with Tidelink("router", "--listen", endpoint, "--certs", str(certs)) as router:
        router.wait_for("zenoh router listening on tls/", WAIT_S, stdout=True)
        r = cli("graph", "--connect", endpoint, "--certs", str(other_certs))
        assert r.returncode == 1
        assert f"cannot reach the router at {endpoint.replace('tcp/', 'tls/')}" in r.stderr
        assert "the router uses another CA" in r.stderr, r.stderr
        r = cli("graph", "--connect", endpoint)  # plain tcp/ to a TLS-only router
        assert r.returncode == 1 and "the router speaks TLS" in r.stderr, r.stderr
        router.signal(2)
        assert router.wait(WAIT_S) == 0
