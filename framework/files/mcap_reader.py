"""Reading MCAP recordings, recovering every complete chunk of a truncated file (docs/recording.md).

Reads both dialects :class:`~handflow.framework.files.mcap_writer.McapWriter` writes (CDR and JSON).
"""

from __future__ import annotations

import logging
import os
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.exceptions import EndOfFile
from mcap.records import Attachment, Channel, Footer, Metadata, Schema
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader
from mcap.writer import MCAP0_MAGIC

from .. import keys, wire
from ..messages import Message, MessageError, decode, message_types
from ..ros2.types import decode_cdr, handflow_type
from .mcap_writer import ENCODINGS, MESSAGE_ENCODING, TYPE_KEY, VIEW_KEY, RecordingError, TopicFilter

log = logging.getLogger("handflow.recording")


@dataclass(frozen=True)
class RecordedMessage:
    """One stored message: its topic (the Zenoh key), handflow type, the stored bytes (``encoding`` cdr or json)
    and both times."""

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
        parts = keys.split_key(self.topic)
        return decode_cdr(self.data, self.type_name, parts[1] if parts else "", self.sequence)

    def wire(self) -> tuple[bytes, bytes]:
        """``(payload, attachment)`` to publish on the handflow wire (CDR records as stored)."""
        if self.encoding == MESSAGE_ENCODING:
            return wire.pack(self.decode())
        parts = keys.split_key(self.topic)
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
    channels: dict[str, dict[str, str]] = field(default_factory=dict)  # Zenoh key → {"type", "schema", view info}

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
    # id → (channel, is data, selected, handflow type, Zenoh key)
    channels: dict[int, tuple[Channel, bool, bool, str, str]] = {}
    with f:
        if f.read(len(MCAP0_MAGIC)) != MCAP0_MAGIC:  # empty, a few bytes or another format: not a truncated MCAP
            raise RecordingError(
                f"{path} is not an MCAP file (it does not start with the MCAP magic bytes); pass a .mcap recording"
            )
        f.seek(0)
        records = StreamReader(f, validate_crcs=True).records
        while True:
            try:
                rec = next(records)
            except StopIteration:
                break
            except Exception as exc:
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
                    ch[4],
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
                key = keys.key_of_ros_name(rec.topic)  # old recordings have no leading '/'
                schema = schemas.get(rec.schema_id)
                type_name = rec.metadata.get(TYPE_KEY) or _type_of_schema(schema)
                is_data = not is_view and type_name in message_types() and rec.message_encoding in ENCODINGS
                selected = (is_data or (is_view and include_views)) and (keep is None or keep(key))
                channels[rec.id] = (rec, is_data, selected, type_name, key)
                report.channels[key] = {
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
