"""The handflow wire: a ROS 2 CDR payload plus a Zenoh attachment naming type, source node and sequence number.

As in rmw_zenoh, what gap counting and the monitor need travels outside the message body
(docs/ros2.md).  Attachment layout (little-endian)::

    b"HF\\x01"  int64 seq  uint16 len(source)  source (UTF-8)  type name (UTF-8, the rest)

The stamp is read from the CDR body itself: most handflow wire types start with ``std_msgs/Header``;
the others (``STAMPS`` of :mod:`handflow.framework.ros2.types`: transforms, markers, text) are decoded.
A payload without an attachment is read as the earlier self-describing JSON (:func:`decode`), so
JSON-speaking peers and recordings keep working.  Everything raises only :class:`MessageError`.
"""

from __future__ import annotations

import json
import re
import struct
from dataclasses import dataclass

from .messages import Message, MessageError, decode, message_types
from .ros2.types import STAMPS, decode_cdr, encode_cdr, restamped_cdr

MAGIC = b"HF\x01"
_FIXED = struct.Struct("<qH")
_STAMP = struct.Struct("<iI")


_HEADER_RX = re.compile(
    rb'^\{"type":"([^"]+)","header":\{"source":"((?:[^"\\]|\\.)*)","seq":(-?\d+),"stamp_ns":(-?\d+)\}'
)


@dataclass(frozen=True)
class WireHeader:
    """Type and header of an encoded message, read without decoding its payload."""

    type_name: str
    source: str
    seq: int
    stamp_ns: int


def peek_header(data: bytes) -> WireHeader:
    """The message type and header of :func:`encode` bytes (fast path on the fixed key order).

    Any other bytes raise :class:`MessageError`; the payload itself is not validated (:func:`decode` does).
    """
    try:
        m = _HEADER_RX.match(data[:512])
        if m:
            source = json.loads(b'"' + m.group(2) + b'"')
            return WireHeader(m.group(1).decode(), source, int(m.group(3)), int(m.group(4)))
        d = json.loads(bytes(data))
        h = d["header"] if "header" in d else {}
        seq, stamp = h.get("seq", 0), h.get("stamp_ns", 0)
        if type(d["type"]) is not str or type(seq) is not int or type(stamp) is not int:
            raise TypeError("type, header.seq and header.stamp_ns must be a string and integers")
        return WireHeader(d["type"], str(h.get("source", "")), seq, stamp)
    except (ValueError, KeyError, TypeError, AttributeError, RecursionError) as exc:
        raise MessageError(f"not a handflow message: {str(exc)[:200]}") from None


def attachment(type_name: str, source: str, seq: int) -> bytes:
    raw = source.encode()
    return MAGIC + _FIXED.pack(seq, len(raw)) + raw + type_name.encode()


def pack(msg: Message) -> tuple[bytes, bytes]:
    """``(payload, attachment)`` of a message whose header is filled in."""
    h = msg.header
    return encode_cdr(msg), attachment(msg.TYPE, h.source, h.seq)


def repack(msg: Message, body: bytes) -> tuple[bytes, bytes] | None:
    """:func:`pack` of a message that is unchanged since it was decoded from the CDR ``body``: the body
    again with the header's stamp (:mod:`handflow.framework.runtime.forwarding`); ``None`` when the type's
    body holds more of the header than the stamp."""
    h = msg.header
    payload = restamped_cdr(body, msg.TYPE, h.stamp_ns)
    return None if payload is None else (payload, attachment(msg.TYPE, h.source, h.seq))


def parse_attachment(att: bytes) -> tuple[str, str, int]:
    """``(type name, source, seq)``; :class:`MessageError` for anything that is not a handflow attachment."""
    fixed = len(MAGIC) + _FIXED.size
    if len(att) < fixed or att[: len(MAGIC)] != MAGIC:
        raise MessageError(f"not a handflow attachment ({len(att)} bytes, starts {bytes(att[:3])!r})")
    seq, n = _FIXED.unpack_from(att, len(MAGIC))
    if seq < 0 or len(att) < fixed + n:
        raise MessageError(f"malformed handflow attachment (seq {seq}, source of {n} bytes)")
    try:
        source, type_name = bytes(att[fixed : fixed + n]).decode(), bytes(att[fixed + n :]).decode()
    except UnicodeDecodeError as exc:
        raise MessageError(f"malformed handflow attachment: {exc}") from None
    if type_name not in message_types():
        raise MessageError(f"unknown message type {type_name[:60]!r} in the attachment")
    return type_name, source, seq


def unpack(payload: bytes, att: bytes | None) -> Message:
    """The checked message of a wire sample (JSON when there is no attachment)."""
    if att is None:
        return decode(payload)
    type_name, source, seq = parse_attachment(att)
    return decode_cdr(payload, type_name, source, seq)


def peek(payload: bytes, att: bytes | None) -> WireHeader:
    """Type, source, seq and stamp of a wire sample without decoding the body."""
    if att is None:
        return peek_header(payload)
    type_name, source, seq = parse_attachment(att)
    if type_name in STAMPS:
        return WireHeader(type_name, source, seq, decode_cdr(payload, type_name).header.stamp_ns)
    if len(payload) < 4 + _STAMP.size:
        raise MessageError(f"a CDR message needs at least {4 + _STAMP.size} bytes, got {len(payload)}")
    sec, nanosec = _STAMP.unpack_from(payload, 4)
    return WireHeader(type_name, source, seq, sec * 1_000_000_000 + nanosec)


def sample_parts(sample) -> tuple[bytes, bytes | None]:
    """Payload and attachment bytes of a Zenoh sample."""
    att = sample.attachment
    return sample.payload.to_bytes(), None if att is None else att.to_bytes()
