"""MCAP recordings: the file layout and the writer (the reader is :mod:`.mcap_reader`).

Recordings open in Foxglove and ROS 2 tools, are readable after a hard kill and keep the publish
time (docs/recording.md).

File layout (what :class:`McapWriter` writes, docs/recording.md).  Default ``encoding="cdr"``: a
rosbag2-compatible MCAP (profile ``ros2``, one ``ros2msg`` schema per ROS 2 type, ``cdr`` messages
from :mod:`handflow.framework.ros2.types`, channel metadata ``handflow.type`` and
``offered_qos_profiles``) that ``rosbags``, ``ros2 bag`` and Foxglove read natively; ``log_time`` =
receive time, ``publish_time`` = header ``stamp_ns``, ``sequence`` = header seq (the source node is
the topic's node).  Channel names are ROS 2 names: the Zenoh key with a leading ``/``
(``/handflow/<graph>/<node>/<port>``, :func:`handflow.framework.keys.ros_name`); the reader accepts
both, so recordings made before the slash read and replay unchanged, and yields Zenoh keys.
``encoding="json"`` writes the earlier handflow JSON dialect:

- one channel per topic (named ``/handflow/<graph>/<node>/<port>`` as above), message encoding
  ``json``, schema encoding ``jsonschema``, schema name = message ``TYPE`` with
  :func:`handflow.framework.messages.json_schema`; each message's data is :func:`handflow.framework.messages.encode`;
  ``log_time`` = receive time, ``publish_time`` = header ``stamp_ns``, ``sequence`` = header seq;
- for ``handflow.Image`` topics also a *view* channel ``<topic>/foxglove_image`` with Foxglove's
  well-known ``foxglove.RawImage`` JSON schema, so the Image panel shows it (documented choice:
  ``foxglove_images=False`` saves the second copy of the pixels);
- zstd chunks (``chunk_size``, default 4 MiB, as the ``mcap`` tool writes them) plus a flush of
  the open chunk every ``flush_interval_s`` (default 1 s): after a ``kill -9`` every complete
  chunk is on disk and :func:`~.mcap_reader.iter_recording` recovers it.  Documented choice: the writer keeps
  one index entry (≈ 1.5 kB with 20 channels) per chunk until it writes the summary, so small
  chunks make a long recording's memory grow (256 kB chunks: ≈ 5 a second in the flagship with
  its camera, ≈ 29 MB an hour); with 4 MiB chunks the 1 s flush cuts most of them (≈ 1 a second);
- metadata/attachments saying how the recording was made (see :class:`~handflow.framework.recorder.graph_recorder.GraphRecorder`).

Helpers for code that writes recordings without the runtime::

    with McapWriter("demo.mcap") as w:
        w.write("handflow/demo/glove/frames", frame, log_time_ns)
    for topic, msg, log_time_ns in mcap_reader.read_messages("demo.mcap"):
        ...
"""

from __future__ import annotations

import json
import logging
import re
import threading
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer

from .. import keys
from ..messages import Image, Message, encode, json_schema, message_types
from ..ros2.types import encode_cdr, ros_type, schema_text

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
    """Globs over ``node/port`` (or over the full key when a glob starts with ``handflow/`` or ``/handflow/``).

    Runtime-internal ports (``_health``, ``_progress``) match only a glob whose port part itself
    starts with ``_`` (e.g. ``*/_health``), so the default ``["**"]`` records data topics only.
    """

    def __init__(self, globs: Iterable[str] | None = None) -> None:
        self.globs = [keys.key_of_ros_name(g) for g in globs] if globs else ["**"]
        self._rx = [(g, _glob_regex(g)) for g in self.globs]

    def __call__(self, key: str) -> bool:
        parts = keys.split_key(key)
        if parts is None:
            return False
        _, node, port = parts
        local = f"{node}/{port}"
        for glob, rx in self._rx:
            target = key if glob.startswith(keys.PREFIX + "/") else local
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
        self._file.flush()  # the magic on disk at once: a file being recorded is never taken for a non-MCAP one
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
            name = keys.ros_name(topic)
            cls = message_types().get(type_name)
            if cls is None:
                raise RecordingError(
                    f"topic '{topic}': unknown message type '{type_name}'; known: {', '.join(sorted(message_types()))}"
                )
            if self.encoding == "cdr":
                meta = {TYPE_KEY: type_name, "offered_qos_profiles": DEFAULT_QOS}
                cid = self._writer.register_channel(name, "cdr", self._ros_schema_id(type_name), meta)
            else:
                sid = self._schema_id(type_name, json_schema(cls))
                cid = self._writer.register_channel(name, MESSAGE_ENCODING, sid, {TYPE_KEY: type_name})
            self._channels[(topic, type_name)] = cid
        return cid

    def _view_channel_id(self, topic: str) -> int:
        view = topic + FOXGLOVE_IMAGE_SUFFIX
        cid = self._channels.get((view, ""))
        if cid is None:
            sid = self._schema_id("foxglove.RawImage", FOXGLOVE_RAW_IMAGE_SCHEMA)
            cid = self._writer.register_channel(keys.ros_name(view), MESSAGE_ENCODING, sid, {VIEW_KEY: topic})
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
        topic = keys.key_of_ros_name(topic)
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
