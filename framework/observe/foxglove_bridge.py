"""Live view in Foxglove: every handflow topic on a Foxglove WebSocket server (foxglove-sdk).

Each topic becomes a ``cdr`` channel with the ``ros2msg`` schema of its ROS 2 type, under the same
name as in recordings (the ROS 2 name ``/handflow/<graph>/<node>/<port>`` of the Zenoh key), so one layout works live
and on a recording (docs/foxglove.md).  The CDR payloads are forwarded as received; Foxglove decodes
them itself (``sensor_msgs/Image`` in the Image panel, ``position[3]`` of a joint state in a Plot).
Runtime-internal topics (``_progress``, ``_clock``) are skipped; heartbeats (``_health``) and runtime
events are shown.  Payloads that are not valid messages are not forwarded (docs/robustness.md).
Serving a replay driven from the playback bar, it forwards nothing from a seek until the replay
reaches the target (:meth:`handflow.framework.recorder.playback.Playback.shows`); a message is checked
and logged under the playback's lock, so one that passed the check is on its way before the seek is
answered.
For one graph, the server also offers Foxglove's Parameters capability (:mod:`.foxglove_params`), and
given the graph file the ConnectionGraph capability (:mod:`.foxglove_graph`).
"""

from __future__ import annotations

import logging
import threading
from typing import TYPE_CHECKING

import zenoh

try:  # the optional extra 'foxglove'
    import foxglove
except ImportError:
    foxglove = None

from .. import wire
from ..keys import PREFIX, ros_name
from ..messages import MessageError, ParamChange
from ..ros2.types import ros_type, schema_text

if TYPE_CHECKING:
    from ..graphs.model import Graph
    from ..recorder.playback import Playback

log = logging.getLogger("handflow.foxglove")
SUBPROTOCOL = "foxglove.sdk.v1"
"""The WebSocket subprotocol foxglove-sdk's server speaks (it refuses a client offering only
``foxglove.websocket.v1``); the apps that offer it: docs/foxglove.md, "Connect"."""
REFUSED_HINT = (
    f"a client that offers no WebSocket subprotocol {SUBPROTOCOL} is refused (HTTP 400): connect with an app "
    f"that offers it (Lichtblick 1.22.0 or newer, a current Foxglove app; docs/foxglove.md, 'Open it in Foxglove')"
)


class _ExplainRefusals(logging.Filter):
    """After foxglove-sdk's "handshake failed" line, a line saying which subprotocol a client needs."""

    def filter(self, record: logging.LogRecord) -> bool:
        if getattr(record, "explained", False) or "handshake failed" not in record.getMessage():
            return True
        record.explained = True
        logging.getLogger(record.name).handle(record)  # the SDK's line first
        log.error(REFUSED_HINT)
        return False


def _explain_refusals() -> None:
    sdk_log = logging.getLogger("foxglove.websocket.server")
    if not any(isinstance(f, _ExplainRefusals) for f in sdk_log.filters):
        sdk_log.addFilter(_ExplainRefusals())


class BridgeError(OSError):
    """The live view cannot start; the message says what to do."""


class PortInUse(BridgeError):
    """The Foxglove port is taken by another program."""


def start_bridge(
    session: zenoh.Session,
    graph: str | list[str],
    host: str,
    port: int,
    params_as: str | None = None,
    spec: Graph | None = None,
    playback: Playback | None = None,
) -> FoxgloveBridge:
    """A running bridge, or :class:`BridgeError` with what to do; ``params_as``: offer the graph's parameters
    (one graph), asking the launcher as this certificate name (``local`` on the graph's own host);
    ``spec``: the loaded graph, shown in Foxglove's Topic Graph panel; ``playback``: a replay driven from
    Foxglove's playback bar (:mod:`handflow.framework.recorder.playback`)."""
    if foxglove is None:
        raise BridgeError("the Foxglove live view needs foxglove-sdk: pip install 'handflow[foxglove]'")
    try:
        return FoxgloveBridge(session, graph, host, port, params_as, spec, playback)
    except Exception as exc:  # foxglove-sdk reports bind failures as a generic error
        if "in use" in str(exc).lower() or "address" in str(exc).lower():
            raise PortInUse(
                f"port {port} on {host} is in use (another handflow or Foxglove bridge?); "
                f"choose another with --foxglove PORT or 'foxglove: {{port: ...}}' in the graph"
            ) from exc
        raise


class FoxgloveBridge:
    """Forward ``handflow/<graph>/**`` of one graph or several (a list) from a Zenoh session to a Foxglove
    WebSocket server."""

    def __init__(
        self,
        session: zenoh.Session,
        graph: str | list[str] = "*",
        host: str = "127.0.0.1",
        port: int = 8765,
        params_as: str | None = None,
        spec: Graph | None = None,
        playback: Playback | None = None,
    ) -> None:
        graphs = [graph] if isinstance(graph, str) else graph
        _explain_refusals()
        self.context = foxglove.Context()
        name = f"handflow {', '.join(graphs)}"
        self.params = None
        capabilities, options = [], {}
        if params_as is not None and len(graphs) == 1:
            from .foxglove_params import ParamsListener

            self.params = ParamsListener(session, graphs[0], params_as)
            capabilities.append(foxglove.Capability.Parameters)
            options["server_listener"] = self.params
        if spec is not None:
            capabilities.append(foxglove.Capability.ConnectionGraph)
        if playback is not None:
            from ..recorder.playback import PlaybackListener

            capabilities += [foxglove.Capability.PlaybackControl, foxglove.Capability.Time]
            options["server_listener"] = PlaybackListener(playback)  # no parameters in a replay
            options["playback_time_range"] = (playback.start_ns, playback.end_ns)
        self.server = foxglove.start_server(
            name=name, host=host, port=port, context=self.context, capabilities=capabilities, **options
        )
        if self.params is not None:  # it tells of refusals and changes through the server
            self.params.server = self.server
        if spec is not None:  # a client that subscribes later receives the current graph
            from .foxglove_graph import connection_graph

            self.server.publish_connection_graph(connection_graph(spec))
        self.port = self.server.port
        self.playback = playback
        self._channels: dict[tuple[str, str], foxglove.Channel] = {}  # (topic, type)
        self._lock = threading.Lock()
        self._subs = [session.declare_subscriber(f"{PREFIX}/{g}/**", self._on_sample) for g in graphs]
        log.info("Foxglove live view on ws://%s:%d (open it in Foxglove: 'Open connection')", host, self.port)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        if key.endswith(("/_progress", "/_clock")):
            return
        payload, att = wire.sample_parts(sample)
        try:
            msg = wire.unpack(payload, att)
            if att is None:  # a JSON-speaking peer: forward its message as CDR
                payload, att = wire.pack(msg)
        except MessageError:
            return
        if self.playback is not None and not self.playback.shows(key, msg.header.seq):
            return
        if self.params is not None and isinstance(msg, ParamChange):
            self.params.changed(msg)
        with self._lock:
            channel = self._channels.get((key, msg.TYPE))
            if channel is None:
                schema = foxglove.Schema(
                    name=ros_type(msg.TYPE), encoding="ros2msg", data=schema_text(msg.TYPE).encode()
                )
                channel = foxglove.Channel(ros_name(key), schema=schema, message_encoding="cdr", context=self.context)
                self._channels[(key, msg.TYPE)] = channel
        if self.playback is None:
            channel.log(payload, log_time=msg.header.stamp_ns or None)
            return
        with self.playback.cond:  # checked again, and logged, before a seek can be answered
            if self.playback.shows(key, msg.header.seq):
                channel.log(payload, log_time=msg.header.stamp_ns or None)

    @property
    def topics(self) -> list[str]:
        with self._lock:
            return sorted({topic for topic, _ in self._channels})

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        self.server.stop()
