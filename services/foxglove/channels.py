"""The Foxglove channels of the view: one generic channel per topic, made from ViewMessages.

A Foxglove WebSocket server does not latch: a client that subscribes to a topic gets only
what is logged afterwards. Every view message is complete in itself (view.py), so each
topic's newest message is kept and logged again when a client subscribes, and a client that
joins mid-run sees the chart, the path and the tracks at once instead of after the next
replan.
"""

from __future__ import annotations

import logging
import queue

import foxglove
from foxglove.websocket import ChannelView, Client, ServerListener

from services.foxglove.view import ViewMessage

log = logging.getLogger("tidelink.foxglove")


class SubscribeListener(ServerListener):
    """Notes which topics clients subscribe to, for the bridge's loop to replay.

    Called on the server's thread: it only enqueues (logging from inside a server callback
    would re-enter the server)."""

    def __init__(self) -> None:
        self.subscribed: queue.SimpleQueue[str] = queue.SimpleQueue()

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.subscribed.put(channel.topic)


class ViewChannels:
    """Logs view messages on channels of a foxglove Context (created on a topic's first
    message, with that message's schema) and keeps each topic's newest message for clients
    that subscribe later (the server's listener: `listener`)."""

    def __init__(self, context: foxglove.Context) -> None:
        self.context = context
        self.listener = SubscribeListener()
        self._channels: dict[str, tuple[foxglove.Channel, tuple[str, str, bytes, str]]] = {}
        self._newest: dict[str, tuple[ViewMessage, int]] = {}
        self.logged = 0

    def log(self, vm: ViewMessage, log_time_ns: int) -> None:
        """Log one view message at log_time_ns (Unix ns) on its topic's channel."""
        self._channel(vm).log(vm.data, log_time=log_time_ns)
        self._newest[vm.topic] = (vm, log_time_ns)
        self.logged += 1

    def replay(self, topic: str) -> None:
        """Log a topic's newest message again (a client just subscribed to it)."""
        kept = self._newest.get(topic)
        if kept is not None:
            vm, log_time_ns = kept
            self._channel(vm).log(vm.data, log_time=log_time_ns)

    def serve_subscriptions(self, timeout_s: float) -> None:
        """Replay the topics clients subscribed to since the last call, waiting up to
        timeout_s for a first one (0: only those already there)."""
        wait: float | None = timeout_s  # a first get may wait; the others take what is there
        while True:
            try:
                if wait is not None and wait > 0:
                    topic = self.listener.subscribed.get(timeout=wait)
                else:
                    topic = self.listener.subscribed.get_nowait()
            except queue.Empty:
                return
            wait = None
            self.replay(topic)

    def forget(self) -> None:
        """Drop the newest messages kept (a new run: the old run's must not be replayed)."""
        self._newest.clear()

    def close(self) -> None:
        for channel, _ in self._channels.values():
            channel.close()
        self._channels.clear()

    def _channel(self, vm: ViewMessage) -> foxglove.Channel:
        schema = (vm.schema_name, vm.schema_encoding, vm.schema, vm.message_encoding)
        known = self._channels.get(vm.topic)
        if known is not None and known[1] == schema:
            return known[0]
        if known is not None:  # the view never does this; a newer tidelink on the bus might
            log.warning("%s changed its schema to %s; re-advertising it", vm.topic, schema[0])
            known[0].close()
        channel = foxglove.Channel(
            vm.topic,
            schema=foxglove.Schema(
                name=vm.schema_name, encoding=vm.schema_encoding, data=vm.schema
            ),
            message_encoding=vm.message_encoding,
            context=self.context,
        )
        self._channels[vm.topic] = (channel, schema)
        return channel
