"""A byte proxy in front of the Foxglove SDK's WebSocket server, so that clients of either
subprotocol name, `foxglove.websocket.v1` or `foxglove.sdk.v1`, are served.

foxglove-sdk 0.30's server accepts a connection only when its Sec-WebSocket-Protocol header
offers `foxglove.sdk.v1` (or `foxglove.sdk.v1.1`), and answers anything else with HTTP 400
"Missing expected sec-websocket-protocol header" (rust/foxglove/src/websocket/handshake.rs);
no option widens it. The Foxglove app offers both names; clients written against the
long-standing ws-protocol specification (foxglove/ws-protocol, docs/spec.md) offer only
`foxglove.websocket.v1`: the protocol `foxglove.sdk.v1` is, under its first name. The proxy
reads each client's opening handshake: one that offers only `foxglove.websocket.v1` is
offered to the SDK as `foxglove.sdk.v1`, and the SDK's answer is given back naming the
subprotocol the client asked for; one that offers an SDK name passes unchanged; one that
offers neither gets a 400 naming them all. After the handshake it copies bytes both ways, so
what the SDK sends (its framing, its back-pressure on a slow client) reaches the client
untouched.
"""

from __future__ import annotations

import contextlib
import logging
import socket
import threading
from collections.abc import Callable

log = logging.getLogger("tidelink.foxglove")

LEGACY = "foxglove.websocket.v1"  # ws-protocol's name of the protocol
SDK = "foxglove.sdk.v1"  # the name the SDK's server requires
# every name the SDK's server accepts (0.30); v1.1 is a revision (schemas advertised apart,
# by id) that the proxy passes through for clients that offer it
SDK_NAMES = (SDK, "foxglove.sdk.v1.1")
ACCEPTED = (LEGACY, *SDK_NAMES)
HEADER = "sec-websocket-protocol"

HANDSHAKE_MAX_BYTES = 16 * 1024  # an opening handshake longer than this is refused
HANDSHAKE_S = 10.0  # the longest a client may take to send its opening handshake
MAX_CLIENTS = 32  # connections served at once; more are refused with 503
CHUNK = 64 * 1024
ACCEPT_POLL_S = 0.25  # how soon the accepting thread sees close()


class HandshakeError(ValueError):
    """A client's opening handshake that is not served: the HTTP status and the reason."""

    def __init__(self, status: str, reason: str) -> None:
        super().__init__(reason)
        self.status = status


def offered(head: bytes) -> list[str]:
    """The subprotocols an HTTP head's Sec-WebSocket-Protocol headers offer, in order."""
    names: list[str] = []
    for line in head.decode("latin-1").split("\r\n")[1:]:
        name, sep, value = line.partition(":")
        if sep and name.strip().lower() == HEADER:
            names += [v.strip() for v in value.split(",") if v.strip()]
    return names


def with_subprotocol(head: bytes, subprotocol: str) -> bytes:
    """An HTTP head whose Sec-WebSocket-Protocol is `subprotocol` alone (other headers kept)."""
    lines = head.decode("latin-1").split("\r\n")
    out, done = [lines[0]], False
    for line in lines[1:]:
        name, sep, _ = line.partition(":")
        if sep and name.strip().lower() == HEADER:
            if not done:
                out.append(f"Sec-WebSocket-Protocol: {subprotocol}")
                done = True
            continue
        out.append(line)
    return "\r\n".join(out).encode("latin-1")


def refusal(status: str, reason: str) -> bytes:
    """A complete plain-text HTTP response that closes the connection."""
    body = (reason + "\n").encode()
    return (
        f"HTTP/1.1 {status}\r\nContent-Type: text/plain; charset=utf-8\r\n"
        f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n"
    ).encode() + body


def plan(head: bytes) -> tuple[bytes, str | None]:
    """What to send the SDK for a client's opening handshake, and the subprotocol its answer
    must name for the client (None: as the SDK says); HandshakeError if it is not served."""
    names = offered(head)
    if any(n in SDK_NAMES for n in names):
        return head, None
    if LEGACY in names:
        return with_subprotocol(head, SDK), LEGACY
    said = f"it offered {', '.join(names)}" if names else "it offered none"
    raise HandshakeError(
        "400 Bad Request",
        "this Foxglove WebSocket server (tidelink foxglove) speaks the subprotocols "
        f"{', '.join(ACCEPTED[:-1])} and {ACCEPTED[-1]}: give one in the Sec-WebSocket-Protocol "
        f"header ({said})",
    )


def read_head(sock: socket.socket, timeout_s: float = HANDSHAKE_S) -> tuple[bytes, bytes]:
    """An HTTP head (without its blank line) and whatever came after it; HandshakeError for
    a head that is too long or does not come in time, ConnectionError if the peer left."""
    sock.settimeout(timeout_s)
    data = b""
    try:
        while b"\r\n\r\n" not in data:
            if len(data) > HANDSHAKE_MAX_BYTES:
                raise HandshakeError("431 Request Header Fields Too Large", "handshake too long")
            chunk = sock.recv(CHUNK)
            if not chunk:
                raise ConnectionError("closed during the handshake")
            data += chunk
    except TimeoutError:
        raise HandshakeError("408 Request Timeout", "no handshake in time") from None
    finally:
        sock.settimeout(None)
    head, _, rest = data.partition(b"\r\n\r\n")
    return head, rest


class SubprotocolProxy:
    """Listens on host:port and serves each client through the SDK's server on
    127.0.0.1:upstream_port (module docstring). Close it to stop: the listener and every
    connection are shut, and every thread is joined."""

    def __init__(self, host: str, port: int, upstream_port: int) -> None:
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        # OSError (the port is taken, the address is not this host's): the caller says so
        self._listener = socket.create_server((host, port), family=family)
        self._listener.settimeout(ACCEPT_POLL_S)
        self.port = int(self._listener.getsockname()[1])
        self.upstream = ("127.0.0.1", upstream_port)
        self._closed = threading.Event()
        self._lock = threading.Lock()
        self._open: set[socket.socket] = set()
        self._threads: list[threading.Thread] = []
        self._acceptor = threading.Thread(target=self._accept, name="foxglove-proxy", daemon=True)
        self._acceptor.start()

    def close(self) -> None:
        """Stop listening, end every connection, join every thread."""
        self._closed.set()
        self._acceptor.join()
        self._listener.close()
        with self._lock:
            for s in self._open:
                with contextlib.suppress(OSError):
                    s.shutdown(socket.SHUT_RDWR)
            threads = list(self._threads)
        for t in threads:
            t.join()

    def __enter__(self) -> SubprotocolProxy:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _accept(self) -> None:
        while not self._closed.is_set():
            try:
                client, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            with self._lock:
                self._threads = [t for t in self._threads if t.is_alive()]
                busy = len(self._threads) >= 2 * MAX_CLIENTS
            if busy:
                with contextlib.suppress(OSError):
                    client.sendall(refusal("503 Service Unavailable", "too many clients"))
                client.close()
                continue
            self._spawn(self._serve, client)

    def _spawn(self, target: Callable[..., None], *args: object) -> threading.Thread:
        t = threading.Thread(target=target, args=args, daemon=True)
        with self._lock:
            self._threads.append(t)
        t.start()
        return t

    def _track(self, s: socket.socket) -> bool:
        """Note an open socket, for close() to shut; False (and it is closed) if closing."""
        with self._lock:
            if self._closed.is_set():
                s.close()
                return False
            self._open.add(s)
            return True

    def _forget(self, *sockets: socket.socket) -> None:
        with self._lock:
            for s in sockets:
                self._open.discard(s)
                s.close()

    def _serve(self, client: socket.socket) -> None:
        if not self._track(client):
            return
        upstream: socket.socket | None = None
        inbound: threading.Thread | None = None  # client -> SDK, on its own thread
        try:
            head, rest = read_head(client)
            to_sdk, name_for_client = plan(head)
            upstream = socket.create_connection(self.upstream, timeout=HANDSHAKE_S)
            upstream.settimeout(None)
            if not self._track(upstream):
                upstream = None
                return
            upstream.sendall(to_sdk + b"\r\n\r\n" + rest)
            if name_for_client is not None:  # the SDK's answer, naming the client's choice
                answer, more = read_head(upstream)
                if SDK in offered(answer):
                    answer = with_subprotocol(answer, name_for_client)
                client.sendall(answer + b"\r\n\r\n" + more)
            inbound = self._spawn(_pump, client, upstream)
            _pump(upstream, client)
        except HandshakeError as exc:
            log.info("refused a Foxglove client: %s", exc)
            with contextlib.suppress(OSError):
                client.sendall(refusal(exc.status, str(exc)))
        except OSError as exc:  # the client or the SDK's server went (ConnectionError too)
            log.debug("a Foxglove client's connection ended: %s", exc)
        finally:
            # shut both ends: the other direction's pump ends; closed only once it has
            for s in (client, upstream):
                if s is not None:
                    with contextlib.suppress(OSError):
                        s.shutdown(socket.SHUT_RDWR)
            if inbound is not None:
                inbound.join()
            self._forget(client, *(() if upstream is None else (upstream,)))


def _pump(src: socket.socket, dst: socket.socket) -> None:
    """Copy bytes from src to dst until src ends or either fails; then shut dst's sending
    side, so the peer sees the end."""
    try:
        while chunk := src.recv(CHUNK):
            dst.sendall(chunk)
    except OSError:
        pass
    finally:
        with contextlib.suppress(OSError):
            dst.shutdown(socket.SHUT_WR)
