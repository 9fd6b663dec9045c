"""Identities for mutual TLS: creation, reuse, validation of bad input, and a real mTLS link."""

from __future__ import annotations

import ipaddress
import json
import os
import shutil
import socket
import stat
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
import zenoh
from cryptography import x509
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from common.bus.certs import (
    DEFAULT_IDENTITIES,
    Credentials,
    CredentialsError,
    _issue_identity,
    _key_pem,
    _sans,
    _write_private,
    ca_paths,
    create_certs,
    identity_paths,
    load_credentials,
    tls_settings,
)
from common.config.errors import ConfigError
from common.runtime.processes.children import free_port

REPO = Path(__file__).resolve().parents[1]


def _cert(path: Path) -> x509.Certificate:
    return x509.load_pem_x509_certificate(path.read_bytes())


def _copy_identity(src: Path, src_name: str, dst: Path, dst_name: str) -> None:
    for src_file, dst_file in zip(
        identity_paths(src, src_name), identity_paths(dst, dst_name), strict=True
    ):
        shutil.copy(src_file, dst_file)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


@pytest.fixture
def certs(tmp_path: Path) -> Path:
    d = tmp_path / "certs"
    create_certs(d, ["router", "planner"])
    return d


# --- creation ------------------------------------------------------------------------------


def test_create_writes_a_ca_and_one_pair_per_identity(tmp_path: Path) -> None:
    d = tmp_path / "certs"
    report = create_certs(d, ["router", "planner"])
    files = [*ca_paths(d), *identity_paths(d, "router"), *identity_paths(d, "planner")]
    assert report == [(f, "created") for f in files]

    ca = _cert(ca_paths(d)[0])
    assert ca.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value == "tidelink CA"
    assert ca.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
    assert ca.extensions.get_extension_for_class(x509.KeyUsage).value.key_cert_sign

    leaf = _cert(identity_paths(d, "planner")[0])
    assert leaf.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value == "planner"
    leaf.verify_directly_issued_by(ca)
    assert not leaf.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
    eku = leaf.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value
    assert set(eku) == {ExtendedKeyUsageOID.CLIENT_AUTH, ExtendedKeyUsageOID.SERVER_AUTH}
    san = leaf.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert set(san.get_values_for_type(x509.IPAddress)) == {
        ipaddress.ip_address("127.0.0.1"),
        ipaddress.ip_address("::1"),
    }
    assert set(san.get_values_for_type(x509.DNSName)) == {"localhost", socket.gethostname()}
    assert leaf.not_valid_after_utc - leaf.not_valid_before_utc <= timedelta(days=365, minutes=5)

    key = serialization.load_pem_private_key(identity_paths(d, "planner")[1].read_bytes(), None)
    assert isinstance(key, ec.EllipticCurvePrivateKey) and key.curve.name == "secp256r1"


def test_hosts_become_ip_and_dns_names(tmp_path: Path) -> None:
    d = tmp_path / "certs"
    create_certs(d, ["router"], hosts=["auv1.lan", "10.0.0.5"], days=7)
    san = _cert(identity_paths(d, "router")[0]).extensions.get_extension_for_class(
        x509.SubjectAlternativeName
    )
    assert san.value.get_values_for_type(x509.DNSName) == ["auv1.lan"]
    assert san.value.get_values_for_type(x509.IPAddress) == [ipaddress.ip_address("10.0.0.5")]


def test_directory_is_0700_and_every_file_0600(tmp_path: Path) -> None:
    d = tmp_path / "deep" / "certs"
    create_certs(d, DEFAULT_IDENTITIES)
    assert _mode(d) == 0o700
    files = sorted(d.iterdir())
    assert len(files) == 2 + 2 * len(DEFAULT_IDENTITIES)
    assert {f.name: _mode(f) for f in files} == {f.name: 0o600 for f in files}
    create_certs(d, ["planner"], renew=True)  # a re-issued file is 0600 from its first byte
    assert {f.name: _mode(f) for f in d.iterdir()} == {f.name: 0o600 for f in files}


def test_second_call_reuses_the_ca_and_keeps_identities(certs: Path) -> None:
    before = {f.name: f.read_bytes() for f in certs.iterdir()}
    report = create_certs(certs, ["planner", "vehicle"])
    assert [what for _, what in report] == ["reused CA"] * 2 + ["kept"] * 2 + ["created"] * 2
    assert {n: (certs / n).read_bytes() for n in before} == before
    ca = _cert(ca_paths(certs)[0])
    _cert(identity_paths(certs, "vehicle")[0]).verify_directly_issued_by(ca)


def test_renew_reissues_from_the_same_ca(certs: Path) -> None:
    ca_before = ca_paths(certs)[0].read_bytes()
    pem_before, key_before = (p.read_bytes() for p in identity_paths(certs, "planner"))
    report = create_certs(certs, ["planner"], renew=True)
    assert [what for _, what in report] == ["reused CA", "reused CA", "created", "created"]
    assert ca_paths(certs)[0].read_bytes() == ca_before
    pem_path, key_path = identity_paths(certs, "planner")
    assert pem_path.read_bytes() != pem_before and key_path.read_bytes() != key_before
    assert load_credentials(certs, "planner").cert == pem_path.absolute()


@pytest.mark.parametrize("lost", [0, 1])
def test_half_a_ca_is_an_error_naming_the_missing_file(certs: Path, lost: int) -> None:
    missing = ca_paths(certs)[lost]
    missing.unlink()
    with pytest.raises(CredentialsError, match="missing while") as err:
        create_certs(certs, ["planner"])
    assert err.value.file == str(missing)


def test_a_kept_identity_from_another_ca_is_an_error(certs: Path, tmp_path: Path) -> None:
    other = tmp_path / "other"
    create_certs(other, ["planner"])
    _copy_identity(other, "planner", certs, "planner")
    with pytest.raises(CredentialsError, match="another CA.*--renew") as err:
        create_certs(certs, ["planner"])
    assert err.value.file == str(identity_paths(certs, "planner")[0])
    create_certs(certs, ["planner"], renew=True)
    load_credentials(certs, "planner")


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"names": ["planner"], "days": 0}, "days: must be >= 1"),
        ({"names": ["plan ner"]}, "names: 'plan ner' must be letters"),
        ({"names": ["../x"]}, "must be letters"),
        ({"names": ["CA"]}, "the CA's file name"),
        ({"names": []}, "at least one identity"),
        ({"names": ["planner"], "hosts": []}, "at least one host"),
        ({"names": ["planner"], "hosts": ["a b"]}, "not an IP address or DNS name"),
    ],
)
def test_bad_arguments_are_config_errors(tmp_path: Path, kwargs: dict, match: str) -> None:
    with pytest.raises(CredentialsError, match=match) as err:
        create_certs(tmp_path / "certs", **kwargs)
    assert isinstance(err.value, ConfigError) and err.value.file == str(tmp_path / "certs")
    assert not (tmp_path / "certs").exists()  # checked before anything is written


# --- loading and validation ----------------------------------------------------------------


def test_load_gives_absolute_paths_and_tls_settings(certs: Path, monkeypatch) -> None:
    monkeypatch.chdir(certs.parent)
    creds = load_credentials(Path("certs"), "planner")
    assert creds == Credentials(
        identity="planner",
        ca=certs / "ca.pem",
        cert=certs / "planner.pem",
        key=certs / "planner.key",
    )
    assert tls_settings(creds, listen=False) == {
        "root_ca_certificate": str(certs / "ca.pem"),
        "enable_mtls": True,
        "verify_name_on_connect": True,
        "close_link_on_expiration": True,
        "connect_private_key": str(certs / "planner.key"),
        "connect_certificate": str(certs / "planner.pem"),
    }
    listening = tls_settings(creds, listen=True)
    assert listening["listen_private_key"] == str(certs / "planner.key")
    assert listening["listen_certificate"] == str(certs / "planner.pem")
    assert listening["connect_certificate"] == str(certs / "planner.pem")


def test_missing_directory(tmp_path: Path) -> None:
    with pytest.raises(CredentialsError, match="no such certificate directory") as err:
        load_credentials(tmp_path / "nowhere", "planner")
    assert err.value.file == str(tmp_path / "nowhere")


@pytest.mark.parametrize("name", ["ca.pem", "planner.pem", "planner.key"])
def test_missing_file(certs: Path, name: str) -> None:
    (certs / name).unlink()
    with pytest.raises(CredentialsError, match="missing: run `tidelink certs") as err:
        load_credentials(certs, "planner")
    assert err.value.file == str(certs / name)
    assert "--names planner" in str(err.value)


def test_unreadable_file(certs: Path) -> None:
    key = certs / "planner.key"
    if os.geteuid() != 0:  # root reads a mode-000 file anyway
        key.chmod(0)
        with pytest.raises(CredentialsError, match="unreadable") as err:
            load_credentials(certs, "planner")
        assert err.value.file == str(key)
        key.unlink()
    else:
        key.unlink()
    key.mkdir()  # unreadable for anyone, root included
    with pytest.raises(CredentialsError, match="unreadable") as err:
        load_credentials(certs, "planner")
    assert err.value.file == str(key)


@pytest.mark.parametrize(
    ("name", "match"),
    [
        ("ca.pem", "not a PEM certificate"),
        ("planner.pem", "not a PEM certificate"),
        ("planner.key", "not a PEM private key"),
    ],
)
def test_garbage_pem(certs: Path, name: str, match: str) -> None:
    (certs / name).write_text("-----BEGIN CERTIFICATE-----\nnot base64\n")
    with pytest.raises(CredentialsError, match=match) as err:
        load_credentials(certs, "planner")
    assert err.value.file == str(certs / name)


def test_key_of_another_identity(certs: Path) -> None:
    shutil.copy(certs / "router.key", certs / "planner.key")
    with pytest.raises(CredentialsError, match="key does not match its certificate") as err:
        load_credentials(certs, "planner")
    assert err.value.file == str(certs / "planner.key")


def test_certificate_from_another_ca(certs: Path, tmp_path: Path) -> None:
    other = tmp_path / "other"
    create_certs(other, ["planner"])
    _copy_identity(other, "planner", certs, "planner")
    with pytest.raises(CredentialsError) as err:
        load_credentials(certs, "planner")
    assert err.value.file == str(certs / "planner.pem")
    assert err.value.problem == f"not signed by {certs / 'ca.pem'}: is it from another CA?"


def test_common_name_must_be_the_identity(certs: Path) -> None:
    _copy_identity(certs, "router", certs, "planner")
    with pytest.raises(CredentialsError, match="its CN is 'router', not 'planner'") as err:
        load_credentials(certs, "planner")
    assert err.value.file == str(certs / "planner.pem")


def test_expired_and_not_yet_valid(certs: Path) -> None:
    leaf = _cert(certs / "planner.pem")
    after = leaf.not_valid_after_utc
    with pytest.raises(CredentialsError, match=f"expired on {after:%Y-%m-%d %H:%M:%S} UTC") as e:
        load_credentials(certs, "planner", now=after + timedelta(seconds=1))
    assert e.value.file == str(certs / "planner.pem")
    with pytest.raises(CredentialsError, match="not valid before") as e:
        load_credentials(certs, "planner", now=datetime.now(UTC) - timedelta(days=1))
    assert e.value.file == str(certs / "planner.pem")
    load_credentials(certs, "planner", now=after - timedelta(seconds=1))


def _expired_identity(certs: Path, into: Path) -> Credentials:
    """A copy of the CA with a planner whose certificate, signed by that CA, expired yesterday."""
    into.mkdir()
    shutil.copy(certs / "ca.pem", into / "ca.pem")
    ca = _cert(certs / "ca.pem")
    ca_key = serialization.load_pem_private_key((certs / "ca.key").read_bytes(), None)
    assert isinstance(ca_key, ec.EllipticCurvePrivateKey)
    key = ec.generate_private_key(ec.SECP256R1())
    now = datetime.now(UTC)
    sans = _sans(str(into), ["127.0.0.1"])
    cert = _issue_identity(
        ca, ca_key, "planner", key, now - timedelta(days=10), now - timedelta(days=1), sans
    )
    cert_path, key_path = identity_paths(into, "planner")
    _write_private(key_path, _key_pem(key))
    _write_private(cert_path, cert.public_bytes(serialization.Encoding.PEM))
    with pytest.raises(CredentialsError, match="expired on"):
        load_credentials(into, "planner")
    return Credentials(
        "planner", (into / "ca.pem").absolute(), cert_path.absolute(), key_path.absolute()
    )


# --- a real mTLS link over Zenoh -----------------------------------------------------------


def _config(mode: str, endpoint: str, tls: dict[str, object] | None) -> zenoh.Config:
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("scouting/multicast/enabled", "false")
    if mode == "router":
        conf.insert_json5("listen/endpoints", json.dumps([endpoint]))
    else:
        conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
        # 0: one attempt, no retries; a refused handshake is final, and the test then takes
        # milliseconds (with 2000 each refusal took 2.0 s, zenoh retrying at 1 s)
        conf.insert_json5("connect/timeout_ms", "0")
        conf.insert_json5("connect/exit_on_failure", "true")
    if tls is not None:
        conf.insert_json5("transport/link/tls", json.dumps(tls))
    return conf


@pytest.fixture
def tls_router(certs: Path) -> Iterator[tuple[int, threading.Event]]:
    """A router listening on tls/127.0.0.1 only, with a subscriber that sets an event."""
    port = free_port()
    router = _config(
        "router",
        f"tls/127.0.0.1:{port}",
        tls_settings(load_credentials(certs, "router"), listen=True),
    )
    got = threading.Event()
    with zenoh.open(router) as session:
        with session.declare_subscriber("tidelink/test/cmd", lambda _sample: got.set()):
            yield port, got


def test_mtls_client_reaches_the_router(
    certs: Path, tls_router: tuple[int, threading.Event]
) -> None:
    port, got = tls_router
    planner = tls_settings(load_credentials(certs, "planner"), listen=False)
    with zenoh.open(_config("client", f"tls/127.0.0.1:{port}", planner)) as client:
        client.put("tidelink/test/cmd", b"go")
        assert got.wait(10.0), "the planner's put did not reach the router over mTLS"


def _refused(endpoint: str, tls: dict[str, object] | None) -> tuple[float, str]:
    """How long zenoh took to refuse to open a client session, and what it said."""
    t0 = time.monotonic()
    with pytest.raises(zenoh.ZError, match="Unable to connect to any of") as err:
        zenoh.open(_config("client", endpoint, tls))
    return time.monotonic() - t0, str(err.value)


def test_mtls_refuses_clients_without_a_good_certificate(
    certs: Path, tmp_path: Path, tls_router: tuple[int, threading.Event]
) -> None:
    port, got = tls_router
    tls = f"tls/127.0.0.1:{port}"
    good = load_credentials(certs, "planner")
    with zenoh.open(_config("client", tls, tls_settings(good, listen=False))):
        pass  # the router is up and takes a good client: what follows is refused for its TLS
    create_certs(tmp_path / "other", ["planner"])
    stranger = load_credentials(tmp_path / "other", "planner")
    cases = {
        "certificate from another CA": (tls, tls_settings(stranger, listen=False)),
        "same, trusting the router's CA": (
            tls,
            tls_settings(replace(stranger, ca=good.ca), listen=False),
        ),
        "plain tcp to the tls port": (f"tcp/127.0.0.1:{port}", None),
        "tls without certificates": (tls, None),
        "tls, router's CA but no certificate": (tls, {"root_ca_certificate": str(good.ca)}),
        "expired certificate": (
            tls,
            tls_settings(_expired_identity(certs, tmp_path / "old"), listen=False),
        ),
    }
    # Each refusal takes ~2 ms; after the first, ~100 ms: zenoh's TLS listener pauses its
    # accept loop 100 ms after every failed handshake (TLS_ACCEPT_THROTTLE_TIME).
    for case, (endpoint, settings) in cases.items():
        elapsed, said = _refused(endpoint, settings)
        print(f"{case}: refused in {elapsed * 1000:.0f} ms: {said}")
        assert elapsed < 5.0, case
    assert not got.is_set()


# --- the CLI -------------------------------------------------------------------------------


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "services.cli", "certs", *args],
        cwd=REPO,
        env={**os.environ, "PYTHONPATH": str(REPO)},
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def test_cli_creates_then_keeps(tmp_path: Path) -> None:
    d = tmp_path / "certs"
    res = _cli(str(d))
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert lines[0].split() == ["created", str(d / "ca.pem")]
    assert len(lines) == 2 + 2 * len(DEFAULT_IDENTITIES) + 1
    assert lines[-1].startswith(f"give --certs {d} to launch/service/router/monitor")
    for name in DEFAULT_IDENTITIES:
        load_credentials(d, name)
    res = _cli(str(d), "--names", "planner, monitor", "--days", "30", "--hosts", "auv1,10.0.0.5")
    assert res.returncode == 0, res.stderr
    assert [line.split()[0] for line in res.stdout.splitlines()[:-1]] == ["reused", "reused"] + [
        "kept"
    ] * 4


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--days", "0"], "days: must be >= 1, got 0"),
        (["--names", "planner,bad name"], "names: 'bad name' must be letters, digits, '_' or '-'"),
    ],
)
def test_cli_bad_input_exits_2(tmp_path: Path, args: list[str], message: str) -> None:
    res = _cli(str(tmp_path / "certs"), *args)
    assert res.returncode == 2
    assert res.stderr.strip() == f"tidelink: config error: {tmp_path / 'certs'}: {message}"
    assert not (tmp_path / "certs").exists()
