"""Why a client could not reach its router, in words a user can act on (TLS or not).

Zenoh says only "Unable to connect to any of [...]" whatever the cause. When that happens we
make one TLS handshake ourselves, with Python's ssl module and the same files, to tell the
causes apart: nothing listens, the router does not speak TLS, it speaks TLS and this client
came without certificates, the router's certificate is from another CA or does not name the
address, or the router refused this client's certificate.
"""

from __future__ import annotations

import socket
import ssl

from common.bus.certs import Credentials
from common.config.bus import tcp_address

PROBE_S = 2.0  # the handshake and the router's verdict on our certificate take milliseconds


def why_unreachable(endpoint: str, creds: Credentials | None) -> str:
    """One sentence on why `endpoint` refused us (empty when the probe cannot tell)."""
    address = tcp_address(endpoint)
    if address is None:
        return ""
    host, port = address
    try:
        raw = socket.create_connection(address, timeout=PROBE_S)
    except OSError as exc:
        return f"nothing accepts connections on {host}:{port} ({exc.strerror or exc})"
    with raw:
        if creds is None:
            return _plain_client(raw, host)
        return _secured_client(raw, host, creds)


def _plain_client(raw: socket.socket, host: str) -> str:
    """We came without TLS: does the router speak it (then the run is secured)?"""
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    ctx.check_hostname = False
    ctx.verify_mode = ssl.CERT_NONE  # only asking whether TLS answers at all
    try:
        with ctx.wrap_socket(raw, server_hostname=host):
            return (
                "the router speaks TLS: this run is secured; connect with --certs DIR "
                "(certificates from the run's CA)"
            )
    except (ssl.SSLError, OSError):
        return ""


def _secured_client(raw: socket.socket, host: str, creds: Credentials) -> str:
    ctx = ssl.create_default_context(cafile=str(creds.ca))
    ctx.load_cert_chain(str(creds.cert), str(creds.key))
    try:
        with ctx.wrap_socket(raw, server_hostname=host) as tls:
            # TLS 1.3: the router judges our certificate after our side of the handshake;
            # a refusal arrives as an alert on the first read, acceptance as silence (the
            # router waits for Zenoh's hello)
            tls.settimeout(PROBE_S)
            try:
                data = tls.recv(1)
            except TimeoutError:
                return ""  # TLS is fine both ways: the failure is elsewhere
            if not data:
                return (
                    f"the router closed the connection after the TLS handshake: it may not "
                    f"accept {creds.cert}"
                )
            return ""
    except ssl.SSLCertVerificationError as exc:
        if "match" in str(exc.verify_message) or "mismatch" in str(exc.verify_message):
            return (
                f"the router's certificate does not name {host}: reissue it with "
                f"`tidelink certs DIR --hosts {host} --renew`"
            )
        return (
            f"the router's certificate is not trusted by {creds.ca} "
            f"({exc.verify_message}): the router uses another CA"
        )
    except ssl.SSLError as exc:
        reason = (exc.reason or str(exc)).upper()
        if "UNKNOWN_CA" in reason or "BAD_CERTIFICATE" in reason or "DECRYPT" in reason:
            return (
                f"the router refused the certificate {creds.cert}: it is not from the router's CA"
            )
        if "EXPIRED" in reason:
            return f"the router refused the certificate {creds.cert}: expired"
        if "WRONG_VERSION" in reason or "RECORD_LAYER" in reason or "PACKET" in reason:
            return "the router does not speak TLS on this port (a plain tcp/ router?)"
        return f"TLS handshake failed: {exc.reason or exc}"
    except TimeoutError:
        return "the router did not answer a TLS handshake: it may listen on plain tcp/"
    except OSError as exc:
        return f"the router closed the connection during the TLS handshake ({exc})"
