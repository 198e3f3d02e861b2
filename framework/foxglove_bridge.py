"""Live view in Foxglove: every handflow topic on a Foxglove WebSocket server (foxglove-sdk).

Each topic becomes a JSON channel whose schema is the message type's JSON schema (the same as in
recordings), named by the topic without the ``handflow/`` prefix (``<graph>/<node>/<port>``).
Images are also published on ``<topic>/foxglove`` with Foxglove's well-known ``RawImage`` schema so
the Image panel shows them; the Plot panel reads fields such as ``positions[3]`` of a joint-state
channel directly.
Runtime-internal topics (``_progress``) are skipped; node heartbeats (``_health``) are shown.
"""

from __future__ import annotations

import logging
import threading

import zenoh

try:  # the optional extra 'foxglove'
    import foxglove
    from foxglove.messages import RawImage, Timestamp
except ImportError:
    foxglove = None

from .messages import Image, MessageError, decode, json_schema
from .transport import PREFIX

log = logging.getLogger("handflow.foxglove")


class BridgeError(OSError):
    """The live view cannot start; the message says what to do."""


class PortInUse(BridgeError):
    """The Foxglove port is taken by another program."""


def start_bridge(session: zenoh.Session, graph: str, host: str, port: int) -> FoxgloveBridge:
    """A running bridge, or :class:`BridgeError` with what to do."""
    if foxglove is None:
        raise BridgeError("the Foxglove live view needs foxglove-sdk: pip install 'handflow[foxglove]'")
    try:
        return FoxgloveBridge(session, graph, host, port)
    except Exception as exc:  # foxglove-sdk reports bind failures as a generic error
        if "in use" in str(exc).lower() or "address" in str(exc).lower():
            raise PortInUse(
                f"port {port} on {host} is in use (another handflow or Foxglove bridge?); "
                f"choose another with --foxglove PORT or 'foxglove: {{port: ...}}' in the graph"
            ) from exc
        raise


class FoxgloveBridge:
    """Forward ``handflow/<graph>/**`` from a Zenoh session to a Foxglove WebSocket server."""

    def __init__(self, session: zenoh.Session, graph: str = "*", host: str = "127.0.0.1", port: int = 8765) -> None:
        self.context = foxglove.Context()
        self.server = foxglove.start_server(name=f"handflow {graph}", host=host, port=port, context=self.context)
        self.port = self.server.port
        self._channels: dict[str, foxglove.Channel] = {}
        self._images: dict[str, foxglove.channels.RawImageChannel] = {}
        self._lock = threading.Lock()
        key = f"{PREFIX}/{graph}/**"
        self._sub = session.declare_subscriber(key, self._on_sample)
        log.info("Foxglove live view on ws://%s:%d (open it in Foxglove: 'Open connection')", host, self.port)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        if key.endswith(("/_progress", "/_clock")):
            return
        payload = sample.payload.to_bytes()
        try:
            msg = decode(payload)
        except MessageError:
            return
        topic = key[len(PREFIX) + 1 :]
        stamp = msg.header.stamp_ns or None
        with self._lock:
            channel = self._channels.get(topic)
            if channel is None:
                channel = foxglove.Channel(
                    topic, schema=json_schema(type(msg)), message_encoding="json", context=self.context
                )
                self._channels[topic] = channel
            if isinstance(msg, Image) and topic not in self._images:
                self._images[topic] = foxglove.channels.RawImageChannel(f"{topic}/foxglove", context=self.context)
        channel.log(payload, log_time=stamp)
        if isinstance(msg, Image):
            ts = Timestamp(msg.header.stamp_ns // 1_000_000_000, msg.header.stamp_ns % 1_000_000_000)
            self._images[topic].log(
                RawImage(
                    timestamp=ts,
                    frame_id=msg.frame_id,
                    width=msg.width,
                    height=msg.height,
                    encoding=msg.encoding,
                    step=msg.step,
                    data=msg.data,
                ),
                log_time=stamp,
            )

    @property
    def topics(self) -> list[str]:
        with self._lock:
            return sorted(self._channels)

    def close(self) -> None:
        self._sub.undeclare()
        self.server.stop()
