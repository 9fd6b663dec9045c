"""Identities of a secured run: a certificate authority and one key + certificate per identity, and their validation."""  # noqa: E501

from __future__ import annotations

import ipaddress
import os
import re
import secrets
import socket
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

from cryptography import x509
from cryptography.exceptions import InvalidSignature, UnsupportedAlgorithm
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.hazmat.primitives.asymmetric.types import PrivateKeyTypes, PublicKeyTypes
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from common.config.errors import ConfigError

DEFAULT_IDENTITIES: tuple[str, ...] = (
    "router",
    "launcher",
    "sensor",
    "estimator",
    "planner",
    "vehicle",
    "monitor",
)
CA_CN = "tidelink CA"
CA_DAYS = 3650  # a new CA outlives the leaves it signs, so renewing them never needs a new CA
# Certificates start a little in the past: a host whose clock lags the issuer's by a few
# minutes would otherwise refuse a certificate issued "in its future".
CLOCK_SKEW = timedelta(minutes=5)
_NAME = re.compile(r"^[A-Za-z0-9_\-]+$")
_EKU = {
    ExtendedKeyUsageOID.CLIENT_AUTH: "clientAuth",
    ExtendedKeyUsageOID.SERVER_AUTH: "serverAuth",
}


class CredentialsError(ConfigError):
    """A certificate directory or one of its files is unusable; the message names the file."""


@dataclass(frozen=True)
class Credentials:
    """An identity's validated files, as absolute paths: the CA certificate, its own pair."""

    identity: str
    ca: Path
    cert: Path
    key: Path


def ca_paths(directory: Path) -> tuple[Path, Path]:
    """The CA's (certificate, key) in `directory`."""
    return directory / "ca.pem", directory / "ca.key"


def identity_paths(directory: Path, name: str) -> tuple[Path, Path]:
    """Identity `name`'s (certificate, key) in `directory`."""
    return directory / f"{name}.pem", directory / f"{name}.key"


def default_hosts() -> list[str]:
    """The names a listener on this machine is reached by: loopback and the host name."""
    return list(dict.fromkeys(["localhost", "127.0.0.1", "::1", socket.gethostname()]))


def create_certs(
    directory: Path,
    names: Sequence[str],
    *,
    days: int = 365,
    hosts: Sequence[str] | None = None,
    renew: bool = False,
) -> list[tuple[Path, str]]:
    """Create (or reuse) the CA in `directory` and a key + certificate for each of `names`.

    Returns each file with what happened to it: "created", "kept" or "reused CA". The CA is
    never overwritten; an identity is re-issued only with `renew`. Every file is mode 0600.
    """
    where = str(directory)
    if days < 1:
        raise CredentialsError(where, "days", f"must be >= 1, got {days}")
    if not names:
        raise CredentialsError(where, "names", "give at least one identity")
    for name in names:
        _check_name(where, "names", name)
    sans = _sans(where, default_hosts() if hosts is None else hosts)
    now = datetime.now(UTC)

    report: list[tuple[Path, str]] = []
    ca_cert_path, ca_key_path = ca_paths(directory)
    if not directory.exists():
        directory.mkdir(parents=True)
        os.chmod(directory, 0o700)  # mkdir's mode is narrowed by the umask; this is exact
    if ca_cert_path.exists() or ca_key_path.exists():
        ca_cert, ca_key = _reuse_ca(ca_cert_path, ca_key_path, now)
        report += [(ca_cert_path, "reused CA"), (ca_key_path, "reused CA")]
    else:
        ca_key = ec.generate_private_key(ec.SECP256R1())
        ca_cert = _issue_ca(ca_key, now - CLOCK_SKEW, now + timedelta(days=max(days, CA_DAYS)))
        _write_private(ca_key_path, _key_pem(ca_key))
        _write_private(ca_cert_path, ca_cert.public_bytes(serialization.Encoding.PEM))
        report += [(ca_cert_path, "created"), (ca_key_path, "created")]

    for name in dict.fromkeys(names):
        cert_path, key_path = identity_paths(directory, name)
        if not renew and (cert_path.exists() or key_path.exists()):
            _check_kept(directory, name, ca_cert, ca_cert_path)
            report += [(cert_path, "kept"), (key_path, "kept")]
            continue
        key = ec.generate_private_key(ec.SECP256R1())
        # a leaf never outlives its CA: webpki checks every certificate of the chain
        not_after = min(now + timedelta(days=days), ca_cert.not_valid_after_utc)
        cert = _issue_identity(ca_cert, ca_key, name, key, now - CLOCK_SKEW, not_after, sans)
        _write_private(key_path, _key_pem(key))
        _write_private(cert_path, cert.public_bytes(serialization.Encoding.PEM))
        report += [(cert_path, "created"), (key_path, "created")]
    return report


def load_credentials(directory: Path, identity: str, *, now: datetime | None = None) -> Credentials:
    """Check `identity`'s files in `directory` before any process starts; CredentialsError if bad.

    `now` (default: the current time, UTC) is when the certificates must be valid.
    """
    _check_name(str(directory), "identity", identity)
    hint = f"run `tidelink certs {directory} --names {identity}`"
    if not directory.is_dir():
        raise CredentialsError(str(directory), "", f"no such certificate directory: {hint}")
    ca_path = ca_paths(directory)[0]
    cert_path, key_path = identity_paths(directory, identity)
    # every file is read before any is parsed, so a missing file is reported as such first
    ca_pem, cert_pem, key_pem = (_read(p, hint) for p in (ca_path, cert_path, key_path))
    ca = _parse_cert(ca_path, ca_pem)
    cert = _parse_cert(cert_path, cert_pem)
    key = _parse_key(key_path, key_pem)
    _check_pair(cert_path, cert, key_path, key)
    cn = _common_name(cert)
    if cn != identity:
        raise CredentialsError(str(cert_path), "", f"its CN is {cn!r}, not {identity!r}")
    _check_signed(cert_path, cert, ca_path, ca)
    at = datetime.now(UTC) if now is None else _utc(now)
    for path, c in ((cert_path, cert), (ca_path, ca)):  # the leaf first: it expires first
        _check_valid(path, c, at)
    usages = _usages(cert)
    for usage, usage_name in _EKU.items():
        if usage not in usages:  # webpki refuses it at the handshake, less clearly
            raise CredentialsError(str(cert_path), "", f"lacks extended key usage {usage_name}")
    return Credentials(
        identity=identity, ca=ca_path.absolute(), cert=cert_path.absolute(), key=key_path.absolute()
    )


def tls_settings(creds: Credentials, *, listen: bool) -> dict[str, object]:
    """The JSON object for Zenoh's config key `transport/link/tls` (names as in zenoh 1.10).

    A listener gets both pairs: a router that also connects out (to another router) needs
    its connect side too, and the same certificate serves both (it has both usages).
    """
    # Key names checked against the TLSConf fields in the zenoh 1.10.2 wheel and against
    # DEFAULT_CONFIG.json5 and zenoh-link-tls on zenoh's main branch. Worth knowing: a
    # connecting side trusts root_ca_certificate *in addition to* the public WebPKI roots,
    # so name verification must stay on; a listener checks a client's chain, validity and
    # clientAuth but no name (the CN is for access_control's cert_common_names);
    # enable_mtls restricts both sides to TLS 1.3; close_link_on_expiration (default
    # false) would cut a live link when a certificate expires; and after every failed
    # handshake the listener pauses accepting for 100 ms (logged with a misleading hint
    # about the open file limit).
    settings: dict[str, object] = {
        "root_ca_certificate": str(creds.ca),
        "enable_mtls": True,
        "verify_name_on_connect": True,
        # an expired certificate ends its links too, not only new connections
        "close_link_on_expiration": True,
    }
    if listen:
        settings |= {"listen_private_key": str(creds.key), "listen_certificate": str(creds.cert)}
    settings |= {"connect_private_key": str(creds.key), "connect_certificate": str(creds.cert)}
    return settings


def _check_name(where: str, key: str, name: str) -> None:
    if not _NAME.match(name):
        raise CredentialsError(where, key, f"{name!r} must be letters, digits, '_' or '-'")
    if name.lower() == "ca":  # its files would be the CA's own (on any file system's case rules)
        raise CredentialsError(where, key, f"{name!r} is the CA's file name, not an identity")


def _sans(where: str, hosts: Sequence[str]) -> list[x509.GeneralName]:
    if not hosts:
        raise CredentialsError(where, "hosts", "give at least one host name or address")
    sans: list[x509.GeneralName] = []
    for host in dict.fromkeys(hosts):
        try:
            sans.append(x509.IPAddress(ipaddress.ip_address(host)))
            continue
        except ValueError:
            pass
        if not host or not host.isascii() or any(c in host for c in " /,"):
            raise CredentialsError(where, "hosts", f"{host!r} is not an IP address or DNS name")
        sans.append(x509.DNSName(host))
    return sans


def _reuse_ca(
    cert_path: Path, key_path: Path, now: datetime
) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
    for present, absent in ((cert_path, key_path), (key_path, cert_path)):
        if not absent.exists():
            raise CredentialsError(
                str(absent),
                "",
                f"missing while {present.name} exists: restore it, or move {present.name} away"
                " to create a new CA (then re-issue every identity with --renew)",
            )
    cert = _parse_cert(cert_path, _read(cert_path, "restore it from a backup"))
    key = _parse_key(key_path, _read(key_path, "restore it from a backup"))
    _check_pair(cert_path, cert, key_path, key)
    _check_valid(cert_path, cert, now)
    if not isinstance(key, ec.EllipticCurvePrivateKey):  # ours are; signing differs per type
        raise CredentialsError(str(key_path), "", f"not an ECDSA key ({type(key).__name__})")
    return cert, key


def _check_kept(directory: Path, name: str, ca: x509.Certificate, ca_path: Path) -> None:
    """An identity kept as it is must still belong to this CA, or the set would not work."""
    cert_path, key_path = identity_paths(directory, name)
    hint = f"re-issue it with `tidelink certs {directory} --names {name} --renew`"
    cert_pem, key_pem = _read(cert_path, hint), _read(key_path, hint)
    try:
        cert, key = _parse_cert(cert_path, cert_pem), _parse_key(key_path, key_pem)
        _check_pair(cert_path, cert, key_path, key)
        _check_signed(cert_path, cert, ca_path, ca)
    except CredentialsError as exc:
        raise CredentialsError(exc.file, exc.key_path, f"{exc.problem}; {hint}") from None


def _issue_ca(
    key: ec.EllipticCurvePrivateKey, not_before: datetime, not_after: datetime
) -> x509.Certificate:
    # Every CA is "tidelink CA"; a random serialNumber attribute (X.520's way to tell apart
    # entities of one name) makes each CA's name unique, so a certificate from another CA
    # is refused as UnknownIssuer / UnknownCA rather than the puzzling BadSignature /
    # DecryptError that rustls reports when the issuer's name matches but its key does not.
    name = x509.Name(
        [
            x509.NameAttribute(NameOID.COMMON_NAME, CA_CN),
            x509.NameAttribute(NameOID.SERIAL_NUMBER, secrets.token_hex(8)),
        ]
    )
    ski = x509.SubjectKeyIdentifier.from_public_key(key.public_key())
    return (
        _builder(name, name, key.public_key(), not_before, not_after)
        # path_length 0: this CA signs identities only, never another CA
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(_key_usage(cert_sign=True), critical=True)
        .add_extension(ski, critical=False)
        .sign(key, hashes.SHA256())
    )


def _issue_identity(
    ca: x509.Certificate,
    ca_key: ec.EllipticCurvePrivateKey,
    name: str,
    key: ec.EllipticCurvePrivateKey,
    not_before: datetime,
    not_after: datetime,
    sans: list[x509.GeneralName],
) -> x509.Certificate:
    """A leaf for `name` signed by the CA; the tests call it directly for an expired one."""
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
    aki = x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key())
    return (
        _builder(subject, ca.subject, key.public_key(), not_before, not_after)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(_key_usage(cert_sign=False), critical=True)
        # both usages: any identity may end up listening (the router+clock process)
        .add_extension(x509.ExtendedKeyUsage(list(_EKU)), critical=False)
        .add_extension(x509.SubjectAlternativeName(sans), critical=False)
        .add_extension(aki, critical=False)
        .sign(ca_key, hashes.SHA256())
    )


def _builder(
    subject: x509.Name,
    issuer: x509.Name,
    public: ec.EllipticCurvePublicKey,
    not_before: datetime,
    not_after: datetime,
) -> x509.CertificateBuilder:
    return (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(issuer)
        .public_key(public)
        .serial_number(x509.random_serial_number())
        .not_valid_before(not_before)
        .not_valid_after(not_after)
    )


def _key_usage(*, cert_sign: bool) -> x509.KeyUsage:
    # ECDSA in TLS 1.3 only signs the handshake: digital_signature is all a leaf needs
    return x509.KeyUsage(
        digital_signature=True,
        content_commitment=False,
        key_encipherment=False,
        data_encipherment=False,
        key_agreement=False,
        key_cert_sign=cert_sign,
        crl_sign=cert_sign,
        encipher_only=False,
        decipher_only=False,
    )


def _key_pem(key: ec.EllipticCurvePrivateKey) -> bytes:
    # PKCS#8, unencrypted: what zenoh's TLS link reads (it tries PKCS#1, PKCS#8, then SEC1)
    return key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )


def _write_private(path: Path, data: bytes) -> None:
    """Write `data` to `path`, mode 0600 from the first byte, replacing it atomically."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    # O_EXCL with mode 0600: the file never exists with wider permissions, and a stale or
    # planted file of that name is an error rather than something we write through
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)  # a crash leaves the old file or the new one, never half of one
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _read(path: Path, hint: str) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise CredentialsError(str(path), "", f"missing: {hint}") from None
    except OSError as exc:  # a directory, no permission, an I/O error
        raise CredentialsError(str(path), "", f"unreadable ({exc.strerror}): {hint}") from None


def _parse_cert(path: Path, pem: bytes) -> x509.Certificate:
    try:
        return x509.load_pem_x509_certificate(pem)
    except ValueError:
        raise CredentialsError(str(path), "", "not a PEM certificate") from None


def _parse_key(path: Path, pem: bytes) -> PrivateKeyTypes:
    try:
        return serialization.load_pem_private_key(pem, password=None)
    except TypeError:  # encrypted: zenoh has no way to be given a passphrase
        raise CredentialsError(
            str(path), "", "encrypted private key (zenoh needs it plain)"
        ) from None
    except (ValueError, UnsupportedAlgorithm):
        raise CredentialsError(str(path), "", "not a PEM private key") from None


def _spki(key: PublicKeyTypes) -> bytes:
    return key.public_bytes(
        serialization.Encoding.DER, serialization.PublicFormat.SubjectPublicKeyInfo
    )


def _check_pair(
    cert_path: Path, cert: x509.Certificate, key_path: Path, key: PrivateKeyTypes
) -> None:
    if _spki(key.public_key()) != _spki(cert.public_key()):
        raise CredentialsError(
            str(key_path), "", f"key does not match its certificate {cert_path.name}"
        )


def _check_signed(
    cert_path: Path, cert: x509.Certificate, ca_path: Path, ca: x509.Certificate
) -> None:
    try:
        cert.verify_directly_issued_by(ca)
    except (ValueError, TypeError, InvalidSignature):
        raise CredentialsError(
            str(cert_path), "", f"not signed by {ca_path}: is it from another CA?"
        ) from None


def _check_valid(path: Path, cert: x509.Certificate, at: datetime) -> None:
    if at > cert.not_valid_after_utc:
        raise CredentialsError(str(path), "", f"expired on {_when(cert.not_valid_after_utc)}")
    if at < cert.not_valid_before_utc:
        raise CredentialsError(
            str(path), "", f"not valid before {_when(cert.not_valid_before_utc)}"
        )


def _common_name(cert: x509.Certificate) -> str:
    names = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
    return str(names[0].value) if names else ""


def _usages(cert: x509.Certificate) -> list[x509.ObjectIdentifier]:
    try:
        return list(cert.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value)
    except x509.ExtensionNotFound:
        return []


def _utc(t: datetime) -> datetime:
    return t.replace(tzinfo=UTC) if t.tzinfo is None else t.astimezone(UTC)  # naive means UTC


def _when(t: datetime) -> str:
    return f"{t:%Y-%m-%d %H:%M:%S} UTC"
