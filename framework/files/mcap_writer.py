"""MCAP recordings: writer, graph recorder, and a reader that recovers truncated files.

Recordings open in Foxglove and ROS 2 tools, are readable after a hard kill and keep the publish
time (docs/recording.md).

File layout (what :class:`McapWriter` writes, docs/recording.md).  Default ``encoding="cdr"``: a
rosbag2-compatible MCAP (profile ``ros2``, one ``ros2msg`` schema per ROS 2 type, ``cdr`` messages
from :mod:`handflow.framework.ros2.types`, channel metadata ``handflow.type`` and
``offered_qos_profiles``) that ``rosbags``, ``ros2 bag`` and Foxglove read natively; ``log_time`` =
receive time, ``publish_time`` = header ``stamp_ns``, ``sequence`` = header seq (the source node is
the topic's node).  ``encoding="json"`` writes the earlier handflow JSON dialect:

- one channel per topic (topic = Zenoh key ``handflow/<graph>/<node>/<port>``), message encoding
  ``json``, schema encoding ``jsonschema``, schema name = message ``TYPE`` with
  :func:`handflow.framework.messages.json_schema`; each message's data is :func:`handflow.framework.messages.encode`;
  ``log_time`` = receive time, ``publish_time`` = header ``stamp_ns``, ``sequence`` = header seq;
- for ``handflow.Image`` topics also a *view* channel ``<topic>/foxglove_image`` with Foxglove's
  well-known ``foxglove.RawImage`` JSON schema, so the Image panel shows it (documented choice:
  ``foxglove_images=False`` saves the second copy of the pixels);
- zstd chunks (``chunk_size``, default 4 MiB, as the ``mcap`` tool writes them) plus a flush of
  the open chunk every ``flush_interval_s`` (default 1 s): after a ``kill -9`` every complete
  chunk is on disk and :func:`iter_recording` recovers it.  Documented choice: the writer keeps
  one index entry (≈ 1.5 kB with 20 channels) per chunk until it writes the summary, so small
  chunks make a long recording's memory grow (256 kB chunks: ≈ 5 a second in the flagship with
  its camera, ≈ 29 MB an hour); with 4 MiB chunks the 1 s flush cuts most of them (≈ 1 a second);
- metadata/attachments saying how the recording was made (see :class:`GraphRecorder`).

Helpers for code that writes recordings without the runtime::

    with McapWriter("demo.mcap") as w:
        w.write("handflow/demo/glove/frames", frame, log_time_ns)
    for topic, msg, log_time_ns in read_messages("demo.mcap"):
        ...
"""

from __future__ import annotations

import json
import logging
import os
import re
import socket
import struct
import threading
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.exceptions import EndOfFile, InvalidMagic
from mcap.records import Attachment, Channel, Footer, Metadata, Schema
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from .. import wire
from ..messages import Image, Message, MessageError, Text, decode, encode, json_schema, message_types
from ..network import sessions as transport
from ..ros2.types import decode_cdr, encode_cdr, handflow_type, ros_type, schema_text
from ..wire import WireHeader, peek_header  # noqa: F401  (re-exported: the JSON dialect's header reader)

log = logging.getLogger("handflow.recording")

SCHEMA_ENCODING = "jsonschema"
MESSAGE_ENCODING = "json"
ENCODINGS = ("cdr", "json")
# what rosbag2 records for a reliable, volatile, keep-last publisher (ros2 bag play offers the same)
DEFAULT_QOS = (
    "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n"
    "  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n"
    "  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n  liveliness: 1\n"
    "  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n"
    "  avoid_ros_namespace_conventions: false"
)
TYPE_KEY = "handflow.type"  # channel metadata: the handflow message type
VIEW_KEY = "handflow.view_of"  # channel metadata of a Foxglove view channel: the source topic
FOXGLOVE_IMAGE_SUFFIX = "/foxglove_image"
MAX_ATTACHED_FILE_BYTES = 64 * 2**20  # files named by params larger than this are listed, not attached

FOXGLOVE_RAW_IMAGE_SCHEMA: dict[str, Any] = {
    "title": "foxglove.RawImage",
    "description": "A raw image",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object",
            "title": "time",
            "properties": {
                "sec": {"type": "integer", "minimum": 0},
                "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
            },
        },
        "frame_id": {"type": "string"},
        "width": {"type": "integer", "minimum": 0},
        "height": {"type": "integer", "minimum": 0},
        "encoding": {"type": "string"},
        "step": {"type": "integer", "minimum": 0},
        "data": {"type": "string", "contentEncoding": "base64"},
    },
}


class RecordingError(ValueError):
    """A recording that cannot be written or read (what is wrong and what to do is in the text)."""


# ----------------------------------------------------------------------------------------------
# Topics and headers
# ----------------------------------------------------------------------------------------------
def _glob_regex(glob: str) -> re.Pattern:
    """``*`` matches within one ``/``-separated segment, ``**`` across segments, ``?`` one char."""
    out = []
    i = 0
    while i < len(glob):
        if glob.startswith("**", i):
            out.append(".*")
            i += 2
        elif glob[i] == "*":
            out.append("[^/]*")
            i += 1
        elif glob[i] == "?":
            out.append("[^/]")
            i += 1
        else:
            out.append(re.escape(glob[i]))
            i += 1
    return re.compile("".join(out) + r"\Z")


class TopicFilter:
    """Globs over ``node/port`` (or over the full key when a glob starts with ``handflow/``).

    Runtime-internal ports (``_health``, ``_progress``) match only a glob whose port part itself
    starts with ``_`` (e.g. ``*/_health``), so the default ``["**"]`` records data topics only.
    """

    def __init__(self, globs: Iterable[str] | None = None) -> None:
        self.globs = list(globs) if globs else ["**"]
        self._rx = [(g, _glob_regex(g)) for g in self.globs]

    def __call__(self, key: str) -> bool:
        parts = transport.split_key(key)
        if parts is None:
            return False
        _, node, port = parts
        local = f"{node}/{port}"
        for glob, rx in self._rx:
            target = key if glob.startswith(transport.PREFIX + "/") else local
            if port.startswith("_") and not glob.rsplit("/", 1)[-1].startswith("_"):
                continue
            if rx.match(target):
                return True
        return False


# ----------------------------------------------------------------------------------------------
# Writer
# ----------------------------------------------------------------------------------------------
class McapWriter:
    """Thread-safe MCAP writer of handflow messages (rosbag2 CDR or JSON channels, chunked, crash-tolerant).

    ``write(topic, msg, log_time_ns)`` encodes and stores a message; ``write_encoded`` stores bytes
    already in the writer's ``encoding`` (:func:`encode_cdr` or :func:`encode`).  ``log_time_ns``
    defaults to the wall clock at the call; ``publish_time_ns`` defaults to the header's ``stamp_ns``.
    """

    CHUNK_SIZE = 4 * 1024 * 1024  # default chunk size (module docstring)

    def __init__(
        self,
        path: str | Path,
        *,
        chunk_size: int = CHUNK_SIZE,
        flush_interval_s: float | None = 1.0,
        foxglove_images: bool = True,
        compression: str = "zstd",
        encoding: str = "cdr",
    ) -> None:
        self.path = Path(path)
        if compression not in ("zstd", "lz4", "none"):
            raise RecordingError(f"compression must be 'zstd', 'lz4' or 'none', got {compression!r}")
        if encoding not in ENCODINGS:
            raise RecordingError(f"encoding must be 'cdr' (rosbag2) or 'json', got {encoding!r}")
        self.encoding = encoding
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = open(self.path, "wb")
        except OSError as exc:
            raise RecordingError(f"cannot write recording {self.path}: {exc.strerror}; choose a writable path") from exc
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=CompressionType[compression.upper()])
        self._writer.start(profile="ros2" if encoding == "cdr" else "", library="handflow")
        self.foxglove_images = foxglove_images and encoding == "json"  # Foxglove shows sensor_msgs/Image itself
        self._lock = threading.Lock()
        self._schemas: dict[str, int] = {}
        self._channels: dict[tuple[str, str], int] = {}  # (topic, type): a second type on a topic gets its own channel
        self.counts: dict[str, int] = {}
        self._dirty = False
        self._closed = False
        self.failure: str | None = None  # why writing stopped (disk full, I/O error), docs/reliability.md
        self._stop = threading.Event()
        self._flusher = None
        if flush_interval_s:
            self._flusher = threading.Thread(
                target=self._flush_loop, args=(flush_interval_s,), name=f"mcap-flush:{self.path.name}", daemon=True
            )
            self._flusher.start()

    # -- channels ---------------------------------------------------------------------------
    def _schema_id(self, name: str, schema: dict[str, Any]) -> int:
        if name not in self._schemas:
            self._schemas[name] = self._writer.register_schema(name, SCHEMA_ENCODING, json.dumps(schema).encode())
        return self._schemas[name]

    def _ros_schema_id(self, type_name: str) -> int:
        ros = ros_type(type_name)
        if ros not in self._schemas:
            self._schemas[ros] = self._writer.register_schema(ros, "ros2msg", schema_text(type_name).encode())
        return self._schemas[ros]

    def _channel_id(self, topic: str, type_name: str) -> int:
        cid = self._channels.get((topic, type_name))
        if cid is None:
            cls = message_types().get(type_name)
            if cls is None:
                raise RecordingError(
                    f"topic '{topic}': unknown message type '{type_name}'; known: {', '.join(sorted(message_types()))}"
                )
            if self.encoding == "cdr":
                meta = {TYPE_KEY: type_name, "offered_qos_profiles": DEFAULT_QOS}
                cid = self._writer.register_channel(topic, "cdr", self._ros_schema_id(type_name), meta)
            else:
                sid = self._schema_id(type_name, json_schema(cls))
                cid = self._writer.register_channel(topic, MESSAGE_ENCODING, sid, {TYPE_KEY: type_name})
            self._channels[(topic, type_name)] = cid
        return cid

    def _view_channel_id(self, topic: str) -> int:
        view = topic + FOXGLOVE_IMAGE_SUFFIX
        cid = self._channels.get((view, ""))
        if cid is None:
            sid = self._schema_id("foxglove.RawImage", FOXGLOVE_RAW_IMAGE_SCHEMA)
            cid = self._writer.register_channel(view, MESSAGE_ENCODING, sid, {VIEW_KEY: topic})
            self._channels[(view, "")] = cid
        return cid

    # -- writing ----------------------------------------------------------------------------
    def write(
        self, topic: str, msg: Message, log_time_ns: int | None = None, publish_time_ns: int | None = None
    ) -> None:
        """Encode ``msg`` and store it on ``topic``."""
        self.write_encoded(
            topic,
            msg.TYPE,
            encode_cdr(msg) if self.encoding == "cdr" else encode(msg),
            log_time_ns,
            msg.header.stamp_ns if publish_time_ns is None else publish_time_ns,
            msg.header.seq,
        )

    def write_encoded(
        self,
        topic: str,
        type_name: str,
        data: bytes,
        log_time_ns: int | None = None,
        publish_time_ns: int = 0,
        sequence: int = 0,
    ) -> None:
        """Store message bytes already in this writer's ``encoding`` (type named by the sender)."""
        with self._lock:
            if self._closed:
                raise RecordingError(self.failure or f"recording {self.path} is closed; open a new McapWriter")
            cid = self._channel_id(topic, type_name)
            log_time = time.time_ns() if log_time_ns is None else int(log_time_ns)
            self._checked(self._writer.add_message, cid, log_time, data, int(publish_time_ns), sequence & 0xFFFFFFFF)
            if type_name == Image.TYPE and self.foxglove_images:
                self._checked(
                    self._writer.add_message,
                    self._view_channel_id(topic),
                    log_time,
                    _foxglove_image(data, publish_time_ns),
                    int(publish_time_ns),
                    sequence & 0xFFFFFFFF,
                )
            self.counts[topic] = self.counts.get(topic, 0) + 1
            self._dirty = True

    def _fail(self, exc: OSError) -> str:
        """Stop writing after an OS error (disk full, file too large): the complete chunks stay readable."""
        self.failure = (
            f"recording stopped: cannot write {self.path} ({exc.strerror or exc}) after {self.message_count} "
            f"message(s); the file holds every complete chunk written before (`handflow inspect {self.path}`); "
            "free disk space or record to another disk"
        )
        self._closed = True
        self._stop.set()
        try:
            self._file.close()
        except OSError:
            pass  # the buffered tail cannot be written either; the reader recovers the complete chunks
        log.error("%s", self.failure)
        return self.failure

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        with self._lock:
            self._checked(self._writer.add_metadata, name, {str(k): str(v) for k, v in data.items()})

    def add_attachment(self, name: str, data: bytes, media_type: str = "application/octet-stream") -> None:
        now = time.time_ns()
        with self._lock:
            self._checked(self._writer.add_attachment, now, now, name, media_type, bytes(data))

    def _checked(self, write, *args) -> None:
        """One write to the file; an OS error stops the recording (:meth:`_fail`) as a :class:`RecordingError`."""
        if self._closed:
            raise RecordingError(self.failure or f"recording {self.path} is closed; open a new McapWriter")
        try:
            write(*args)
        except OSError as exc:
            raise RecordingError(self._fail(exc)) from None

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())

    # -- durability -------------------------------------------------------------------------
    def flush(self) -> None:
        """Close the open chunk and hand everything to the OS (survives a kill of this process)."""
        with self._lock:
            if not self._closed and self._dirty:
                try:
                    self._writer.flush()
                except OSError as exc:
                    self._fail(exc)
                    return
                self._dirty = False

    def _flush_loop(self, interval: float) -> None:
        while not self._stop.wait(interval):
            self.flush()

    def close(self) -> None:
        """Write the summary and footer (idempotent)."""
        self._stop.set()
        if self._flusher is not None and self._flusher is not threading.current_thread():
            self._flusher.join()
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                self._writer.finish()
                self._file.close()
            except OSError as exc:
                self._fail(exc)

    def __enter__(self) -> McapWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _foxglove_image(data: bytes, stamp_ns: int) -> bytes:
    """A ``handflow.Image`` payload as ``foxglove.RawImage`` JSON (pixels stay base64)."""
    d = json.loads(data)
    stamp = max(int(stamp_ns), 0)
    view = {
        "timestamp": {"sec": stamp // 1_000_000_000, "nsec": stamp % 1_000_000_000},
        **{k: d[k] for k in ("frame_id", "width", "height", "encoding", "step", "data")},
    }
    return json.dumps(view, separators=(",", ":")).encode()


# ----------------------------------------------------------------------------------------------
# Recording a running graph
# ----------------------------------------------------------------------------------------------
def graph_provenance(graph: Any) -> tuple[dict[str, dict[str, str]], dict[str, tuple[str, bytes]]]:
    """Metadata records and attachments that say how a recording of ``graph`` was made.

    Metadata: ``handflow.graph`` (name, file, host, start time), ``handflow.params`` (node id →
    resolved params as JSON), ``handflow.plugins`` (node id → plugin), ``handflow.files``
    (``node.param`` → attachment name, or a note why the file is not attached).
    Attachments: ``graph.yaml`` (the graph file) and every existing file a param names
    (resolved relative to the graph folder), as ``files/<path>``.
    """
    meta = {
        "handflow.graph": {
            "name": graph.name,
            "file": str(graph.path),
            "host": socket.gethostname(),
            "started_ns": str(time.time_ns()),
        },
        "handflow.params": {nid: json.dumps(rn.params.model_dump(mode="json")) for nid, rn in graph.nodes.items()},
        "handflow.plugins": {nid: rn.spec.plugin for nid, rn in graph.nodes.items()},
    }
    attachments: dict[str, tuple[str, bytes]] = {}
    try:
        attachments["graph.yaml"] = ("application/yaml", graph.path.read_bytes())
    except OSError as exc:
        log.warning("graph file %s not attached: %s", graph.path, exc.strerror)
    files: dict[str, str] = {}
    for nid, rn in graph.nodes.items():
        for name, value in _string_leaves(rn.params.model_dump(mode="json")):
            path = _existing_file(graph.base_dir, value)
            if path is None:
                continue
            label = f"{nid}.{name}"
            size = path.stat().st_size
            if size > MAX_ATTACHED_FILE_BYTES:
                files[label] = f"not attached: {path} is {size} bytes (limit {MAX_ATTACHED_FILE_BYTES})"
                continue
            try:
                rel = path.relative_to(graph.base_dir)
            except ValueError:
                rel = Path(str(path).lstrip("/"))
            att = f"files/{rel.as_posix()}"
            attachments.setdefault(att, ("application/octet-stream", path.read_bytes()))
            files[label] = att
    meta["handflow.files"] = files
    return meta, attachments


def _string_leaves(value: Any, prefix: str = "") -> Iterator[tuple[str, str]]:
    if isinstance(value, str):
        yield prefix, value
    elif isinstance(value, dict):
        for k, v in value.items():
            yield from _string_leaves(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _string_leaves(v, f"{prefix}[{i}]")


def _existing_file(base: Path, value: str) -> Path | None:
    if not value or "\n" in value or len(value) > 4096:
        return None
    p = Path(value).expanduser()
    p = p if p.is_absolute() else base / p
    try:
        return p.resolve() if p.is_file() else None
    except OSError:
        return None


class GraphRecorder:
    """Records a graph's topics from a Zenoh session into an :class:`McapWriter`.

    ``GraphRecorder.for_graph(graph, path)`` also stores the graph's provenance
    (:func:`graph_provenance`); ``attach(session)`` subscribes to ``handflow/<graph>/**`` and keeps
    the topics matching the ``record.topics`` globs; ``close()`` finalises the file.
    Payloads are validated by :func:`decode` and stored as received (never re-encoded); invalid
    payloads are counted in ``skipped`` and logged once per topic.  The first :class:`Text` document
    of each topic (e.g. a robot description) is also attached as a file named after the topic
    (``handflow/demo/sim/description.urdf`` for a URDF; docs/foxglove.md).
    """

    def __init__(self, writer: McapWriter, graph_name: str, topics: Iterable[str] | None = None) -> None:
        self.writer = writer
        self.graph_name = graph_name
        self.filter = TopicFilter(topics)
        self.skipped: dict[str, int] = {}
        self._subscriber = None
        self._documents: set[str] = set()

    @classmethod
    def for_graph(
        cls, graph: Any, path: str | Path, topics: Iterable[str] | None = None, **writer_kw: Any
    ) -> GraphRecorder:
        if topics is None:
            topics = graph.spec.record.topics if graph.spec.record else None
        writer = McapWriter(path, **writer_kw)
        meta, attachments = graph_provenance(graph)
        for name, data in meta.items():
            writer.add_metadata(name, data)
        for name, (media_type, data) in attachments.items():
            writer.add_attachment(name, data, media_type)
        return cls(writer, graph.name, topics)

    def attach(self, session: Any) -> None:
        self._subscriber = session.declare_subscriber(f"{transport.PREFIX}/{self.graph_name}/**", self._on_sample)

    def _on_sample(self, sample: Any) -> None:
        key = str(sample.key_expr)
        if not self.filter(key):
            return
        data, att = wire.sample_parts(sample)
        try:
            msg = wire.unpack(data, att)  # what replay and Foxglove read back must be valid (docs/robustness.md)
            if (att is not None) == (
                self.writer.encoding == "cdr"
            ):  # already in the file's encoding: stored as received
                self.writer.write_encoded(key, msg.TYPE, data, None, msg.header.stamp_ns, msg.header.seq)
            else:
                self.writer.write(key, msg)
            if isinstance(msg, Text) and key not in self._documents:
                self._documents.add(key)
                self._attach_document(key, msg.data)
        except (MessageError, RecordingError) as exc:
            if self.writer.failure:
                return  # reported once by the writer
            if key not in self.skipped:
                log.warning("not recording a payload on %s: %s", key, exc)
            self.skipped[key] = self.skipped.get(key, 0) + 1

    def _attach_document(self, key: str, text: str) -> None:
        urdf = "<robot" in text[:2000]
        name, media_type = (f"{key}.urdf", "application/xml") if urdf else (f"{key}.txt", "text/plain")
        self.writer.add_attachment(name, text.encode(), media_type)

    def close(self) -> None:
        if self._subscriber is not None:
            self._subscriber.undeclare()
            self._subscriber = None
        self.writer.close()
        log.info(
            "recorded %d message(s) on %d topic(s) to %s",
            self.writer.message_count,
            len(self.writer.counts),
            self.writer.path,
        )


# ----------------------------------------------------------------------------------------------
# Reading (with recovery of truncated files)
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RecordedMessage:
    """One stored message: its topic, handflow type, the stored bytes (``encoding`` cdr or json) and both times."""

    topic: str
    type_name: str
    data: bytes
    log_time_ns: int
    publish_time_ns: int
    sequence: int
    encoding: str = MESSAGE_ENCODING

    def decode(self) -> Message:
        """The message, with header source (the topic's node) and seq (the MCAP sequence) for CDR records."""
        if self.encoding == MESSAGE_ENCODING:
            return decode(self.data)
        parts = transport.split_key(self.topic)
        return decode_cdr(self.data, self.type_name, parts[1] if parts else "", self.sequence)

    def wire(self) -> tuple[bytes, bytes]:
        """``(payload, attachment)`` to publish on the handflow wire (CDR records as stored)."""
        if self.encoding == MESSAGE_ENCODING:
            return wire.pack(self.decode())
        parts = transport.split_key(self.topic)
        return self.data, wire.attachment(self.type_name, parts[1] if parts else "", self.sequence)


@dataclass
class ReadReport:
    """What a pass over a recording found; ``complete`` is False for a truncated/damaged file."""

    path: Path
    complete: bool = False
    messages: int = 0
    error: str = ""
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: dict[str, Attachment] = field(default_factory=dict)
    channels: dict[str, dict[str, str]] = field(default_factory=dict)  # topic → {"type", "schema", view info}

    @property
    def recovered(self) -> bool:
        return not self.complete

    def describe(self) -> str:
        if self.complete:
            return f"{self.path}: complete recording, {self.messages} message(s)"
        return (
            f"{self.path}: truncated or damaged recording ({self.error}); recovered {self.messages} message(s) "
            f"from its complete chunks"
        )


def iter_recording(
    path: str | Path,
    topics: Iterable[str] | None = None,
    *,
    report: ReadReport | None = None,
    include_views: bool = False,
) -> Iterator[RecordedMessage]:
    """Messages of a recording in file order; a truncated file yields every complete chunk.

    ``topics``: :class:`TopicFilter` globs (None: all data topics).  Foxglove view channels are
    skipped unless ``include_views``.  Pass a :class:`ReadReport` to learn whether the file was
    complete and how many messages were read.  Chunk CRCs are checked, so a half-written chunk is
    never yielded.
    """
    path = Path(path)
    report = report if report is not None else ReadReport(path)
    report.path = path
    keep = TopicFilter(topics) if topics is not None else None
    try:
        f = open(path, "rb")
    except OSError as exc:
        raise RecordingError(f"cannot read recording {path}: {exc.strerror}") from exc
    schemas: dict[int, Schema] = {}
    channels: dict[int, tuple[Channel, bool, bool, str]] = {}  # id → (channel, is data, selected, handflow type)
    with f:
        records = StreamReader(f, validate_crcs=True).records
        while True:
            try:
                rec = next(records)
            except StopIteration:
                break
            except Exception as exc:
                if isinstance(exc, InvalidMagic) and not schemas and not report.complete:
                    raise RecordingError(
                        f"{path} is not an MCAP file (bad magic bytes); pass a .mcap recording"
                    ) from exc
                report.error = _describe_read_error(exc, f)
                log.warning("%s", report.describe())
                return
            if isinstance(rec, McapMessage):
                ch = channels.get(rec.channel_id)
                if ch is None or not ch[2]:
                    continue
                report.messages += 1
                channel = ch[0]
                yield RecordedMessage(
                    channel.topic,
                    ch[3],
                    rec.data,
                    rec.log_time,
                    rec.publish_time,
                    rec.sequence,
                    channel.message_encoding,
                )
            elif isinstance(rec, Schema):
                schemas[rec.id] = rec
            elif isinstance(rec, Channel):
                if rec.id in channels:
                    continue
                is_view = VIEW_KEY in rec.metadata
                schema = schemas.get(rec.schema_id)
                type_name = rec.metadata.get(TYPE_KEY) or _type_of_schema(schema)
                is_data = not is_view and type_name in message_types() and rec.message_encoding in ENCODINGS
                selected = (is_data or (is_view and include_views)) and (keep is None or keep(rec.topic))
                channels[rec.id] = (rec, is_data, selected, type_name)
                report.channels[rec.topic] = {
                    "type": type_name,
                    "schema": schema.name if schema else "",
                    **({"view_of": rec.metadata[VIEW_KEY]} if is_view else {}),
                }
            elif isinstance(rec, Metadata):
                report.metadata[rec.name] = dict(rec.metadata)
            elif isinstance(rec, Attachment):
                report.attachments[rec.name] = rec
            elif isinstance(rec, Footer):
                report.complete = True


def _type_of_schema(schema: Schema | None) -> str:
    """The handflow type of a channel without ``handflow.type`` metadata (e.g. written by ROS 2 tools)."""
    if schema is None:
        return ""
    if schema.encoding != "ros2msg":
        return schema.name
    try:
        return handflow_type(schema.name).TYPE
    except MessageError:
        return ""


def _describe_read_error(exc: Exception, f: Any) -> str:
    try:
        where = f"byte {f.tell()} of {os.fstat(f.fileno()).st_size}"
    except (OSError, ValueError):
        where = "an unknown offset"
    if isinstance(exc, (EndOfFile, struct.error)):
        return f"the file ends inside a record at {where}"
    return f"{type(exc).__name__}: {exc} at {where}"


def read_messages(path: str | Path, topics: Iterable[str] | None = None) -> Iterator[tuple[str, Message, int]]:
    """``(topic, message, log_time_ns)`` for every data message (truncated files: what was recovered)."""
    for rm in iter_recording(path, topics):
        yield rm.topic, rm.decode(), rm.log_time_ns


def read_report(path: str | Path) -> ReadReport:
    """Read a whole recording and return its :class:`ReadReport` (counts, metadata, attachments)."""
    report = ReadReport(Path(path))
    for _ in iter_recording(path, report=report):
        pass
    return report
