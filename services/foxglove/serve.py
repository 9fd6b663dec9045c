"""`tidelink foxglove`'s process: a Foxglove WebSocket server fed by the bridge, across runs
and the routers they bring (docs/monitoring.md). Clients reach it through a proxy that lets
them speak either subprotocol name, foxglove.websocket.v1 or foxglove.sdk.v1
(subprotocol.py)."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import foxglove
from foxglove import StatusLevel
from foxglove.websocket import WebSocketServer

from common.bus import Bus, Keys
from common.bus.watcher import Watcher
from common.config.bus import WatchTarget, client_config
from common.runtime.processes.children import wait_for_endpoint
from services.foxglove.bridge import FoxgloveBridge
from services.foxglove.channels import ViewChannels
from services.foxglove.subprotocol import LEGACY, SDK, SubprotocolProxy

log = logging.getLogger("tidelink.foxglove")

ROUTER_PROBE_S = 0.5  # between attempts to reach a router that is not there


@dataclass(frozen=True, kw_only=True)
class BridgeOptions(WatchTarget):
    """Where the runs are and which to show (with run None: the first run that is on, then
    the next, and so on), and where to serve the app."""

    host: str = "127.0.0.1"
    port: int = 8765


@dataclass(frozen=True)
class Served:
    """The SDK's WebSocket server of the channels (on a loopback port of its own) behind the
    proxy clients reach on host:port, which serves both subprotocol names (subprotocol.py)."""

    sdk: WebSocketServer
    proxy: SubprotocolProxy

    @property
    def port(self) -> int:
        """The port clients connect to."""
        return self.proxy.port

    def stop(self) -> None:
        self.proxy.close()
        self.sdk.stop()


def start_server(opts: BridgeOptions, channels: ViewChannels) -> Served:
    """The WebSocket server of the channels; OSError naming the port if it cannot serve."""
    try:
        sdk = foxglove.start_server(
            name="tidelink",
            host="127.0.0.1",
            port=0,
            server_listener=channels.listener,
            context=channels.context,
        )
    except RuntimeError as exc:  # the SDK's FoxgloveError
        raise OSError(f"foxglove: cannot start the WebSocket server: {exc}") from None
    try:
        return Served(sdk, SubprotocolProxy(opts.host, opts.port, sdk.port))
    except OSError as exc:  # e.g. "Address already in use"
        sdk.stop()
        raise OSError(
            f"foxglove: cannot serve on {opts.host}:{opts.port}: {exc.strerror or exc} "
            "(another bridge on this port? choose one with --port)"
        ) from None


def serve(opts: BridgeOptions) -> None:
    """Serve the runs on opts.connect to Foxglove clients on ws://host:port until a signal
    (Shutdown or KeyboardInterrupt) ends it; the bus and the server close on the way out."""
    # not the global context: a recorder in the same process keeps its own channels
    channels = ViewChannels(foxglove.Context())
    served = start_server(opts, channels)
    server = served.sdk
    try:
        log.info(
            "serving Foxglove on ws://%s:%d (subprotocol %s or %s)",
            opts.host,
            served.port,
            LEGACY,
            SDK,
        )
        while True:
            _wait_for_router(opts.connect, server, channels)
            cfg = client_config(opts.connect, opts.certs)
            try:
                with Bus(
                    cfg, Keys(opts.run or "any", opts.vehicle or "any"), identity=opts.identity
                ) as bus:
                    watcher = Watcher(bus, opts.run, opts.vehicle)
                    watcher.start()
                    bridge = FoxgloveBridge(watcher, server, channels, opts.connect)
                    bridge.run_while(lambda: wait_for_endpoint(opts.connect, 0.0))
            except ConnectionError as exc:  # it went between our probe and Zenoh's connect,
                # or what listens there is no Zenoh router: try again, without spinning
                log.warning("%s; trying again", exc)
                channels.serve_subscriptions(ROUTER_PROBE_S)
                continue
            log.info("the router at %s is gone", opts.connect)
    finally:
        channels.close()
        served.stop()


def _wait_for_router(endpoint: str, server: WebSocketServer, channels: ViewChannels) -> None:
    """Return once the router accepts connections (at once if it does), saying so if not;
    meanwhile a client that subscribes still gets the last run's newest messages."""
    if wait_for_endpoint(endpoint, 0.0):
        return
    log.info("no router at %s yet; waiting for one", endpoint)
    server.publish_status(f"waiting for the router at {endpoint}", StatusLevel.Info)
    while not wait_for_endpoint(endpoint, 0.0):
        channels.serve_subscriptions(ROUTER_PROBE_S)
