"""The Foxglove channels of the view: one generic channel per topic, made from ViewMessages.

A Foxglove WebSocket server does not latch: a client that subscribes to a topic gets only
what is logged afterwards. Every view message is complete in itself (view.py), so each
topic's newest message is kept and logged again when a client subscribes, and a client that
joins mid-run sees the chart, the path and the tracks at once instead of after the next
replan. A topic's first message travels only so: no client has its channel before it is
advertised, and logging it at once as well reached a client twice when its subscription
overtook the log.

A subscription the server refused as to an "unknown channel" is mended by advertising that
channel again (`LostSubscriptions`): the SDK's server (foxglove-sdk 0.30) sends a channel's
advertisement to a connected client before it records the channel as advertised to it, so a
client that answers at once, on the same machine, may subscribe in between and be refused;
it is not told again, and the topic stays dark for it
(docs/notes/0030-foxglove-re-advertises-a-refused-channel.md).
"""

from __future__ import annotations

import logging
import queue
import re

import foxglove
from foxglove.websocket import ChannelView, Client, ServerListener

from common.view import ViewMessage

log = logging.getLogger("tidelink.foxglove")


class SubscribeListener(ServerListener):
    """Notes which topics clients subscribe to, for the bridge's loop to replay.

    Called on the server's thread: it only enqueues (logging from inside a server callback
    would re-enter the server)."""

    def __init__(self) -> None:
        self.subscribed: queue.SimpleQueue[str] = queue.SimpleQueue()

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.subscribed.put(channel.topic)


# the SDK's server logs a refused subscription through Python's logging (its Rust target as
# the logger's name), naming the channel id
SDK_CLIENT_LOGGER = "foxglove.websocket.connected_client"
_UNKNOWN_CHANNEL = re.compile(r"subscribe to unknown channel: (\d+)")


class LostSubscriptions(logging.Handler):
    """Collects the ids of channels the server refused a client's subscription to as unknown
    (module docstring). Called on the server's thread: it only enqueues."""

    def __init__(self) -> None:
        super().__init__(level=logging.ERROR)
        self.channel_ids: queue.SimpleQueue[int] = queue.SimpleQueue()

    def emit(self, record: logging.LogRecord) -> None:
        found = _UNKNOWN_CHANNEL.search(record.getMessage())
        if found is not None:
            self.channel_ids.put(int(found.group(1)))


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
        self.lost = LostSubscriptions()
        logging.getLogger(SDK_CLIENT_LOGGER).addHandler(self.lost)
        self.readvertised = 0  # channels advertised again after a refused subscription

    def log(self, vm: ViewMessage, log_time_ns: int) -> None:
        """Log one view message at log_time_ns (Unix ns) on its topic's channel; a topic's
        first message only advertises the channel, and reaches each client that subscribes
        through `replay`: logged as well, it would reach twice a client whose subscription came
        between the advertisement and the log."""
        self._newest[vm.topic] = (vm, log_time_ns)
        self.logged += 1
        channel = self._known(vm)
        if channel is None:
            self._advertise(vm)
            return
        channel.log(vm.data, log_time=log_time_ns)

    def replay(self, topic: str) -> None:
        """Log a topic's newest message again (a client just subscribed to it)."""
        kept = self._newest.get(topic)
        if kept is not None:
            vm, log_time_ns = kept
            self._channel(vm).log(vm.data, log_time=log_time_ns)

    def serve_subscriptions(self, timeout_s: float) -> None:
        """Advertise again the channels a subscription to was refused (module docstring),
        then replay the topics clients subscribed to since the last call, waiting up to
        timeout_s for a first one (0: only those already there)."""
        self._readvertise_lost()
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
        logging.getLogger(SDK_CLIENT_LOGGER).removeHandler(self.lost)

    def _readvertise_lost(self) -> None:
        """Close and make again each channel a subscription to was refused: every client is
        told it went and came (unadvertise, advertise under a new id), subscribes to it anew,
        and gets its newest message replayed (`replay`)."""
        while True:
            try:
                lost = self.lost.channel_ids.get_nowait()
            except queue.Empty:
                return
            for topic, (channel, _) in list(self._channels.items()):
                if channel.id() != lost:
                    continue
                newest = self._newest.get(topic)
                channel.close()
                del self._channels[topic]
                self.readvertised += 1
                log.info("a subscription to %s was refused as unknown; advertised it again", topic)
                if newest is not None:
                    self._channel(newest[0])  # again, under a new id

    def _channel(self, vm: ViewMessage) -> foxglove.Channel:
        return self._known(vm) or self._advertise(vm)

    def _known(self, vm: ViewMessage) -> foxglove.Channel | None:
        """The topic's channel if it is advertised with vm's schema (one advertised with
        another is closed)."""
        known = self._channels.get(vm.topic)
        if known is not None and known[1] == _schema(vm):
            return known[0]
        if known is not None:  # the view never does this; a newer tidelink on the bus might
            log.warning("%s changed its schema to %s; re-advertising it", vm.topic, vm.schema_name)
            known[0].close()
            del self._channels[vm.topic]
        return None

    def _advertise(self, vm: ViewMessage) -> foxglove.Channel:
        """A new channel for vm's topic and schema (every client is told of it)."""
        schema = _schema(vm)
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


def _schema(vm: ViewMessage) -> tuple[str, str, bytes, str]:
    """What a channel is advertised with: a view message's schema and encoding."""
    return (vm.schema_name, vm.schema_encoding, vm.schema, vm.message_encoding)
