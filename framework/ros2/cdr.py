"""CDR (XCDR1, little-endian, with the 4-byte encapsulation header) reader and writer driven by ``.msg`` field lists.

The layout rules are those of ROS 2 (rmw_fastrtps/rmw_zenoh): primitives aligned to their size
relative to the byte after the encapsulation header, strings as ``uint32`` length (with the NUL) +
bytes + NUL, sequences as ``uint32`` count + elements.  The reader checks every length against the
bytes left, so a malformed payload raises :class:`MessageError` and never reads past the end;
numeric sequences come back as read-only numpy views of the payload (no copy).  Cross-checked
against ``rosbags`` in tests/framework/test_ros2_cdr.py; docs/ros2.md.
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Callable
from typing import Any

import numpy as np

from ..messages import MessageError

ENCAPSULATION_LE = b"\x00\x01\x00\x00"
PRIMITIVES = {
    "bool": "?",
    "byte": "B",
    "char": "B",
    "uint8": "B",
    "int8": "b",
    "uint16": "H",
    "int16": "h",
    "uint32": "I",
    "int32": "i",
    "uint64": "Q",
    "int64": "q",
    "float32": "f",
    "float64": "d",
}
_STRUCTS = {name: struct.Struct("<" + code) for name, code in PRIMITIVES.items()}
_DTYPES = {name: np.dtype("<" + code) if code != "?" else np.dtype(np.uint8) for name, code in PRIMITIVES.items()}
HEADER = "std_msgs/Header"

Fields = list[tuple[str, str]]  # (type, name) in declaration order


def parse_msg(text: str) -> Fields:
    """Fields of a ``.msg`` definition (comments, blank lines and constants skipped)."""
    fields = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line or "=" in line:
            continue
        ftype, name = line.split()[:2]
        fields.append((ftype, name))
    return fields


class CdrWriter:
    """Appends CDR-encoded values to a buffer that starts with the little-endian encapsulation header."""

    def __init__(self, specs: dict[str, Fields]) -> None:
        self.specs = specs
        self.buf = bytearray(ENCAPSULATION_LE)

    def _align(self, n: int) -> None:
        pad = -(len(self.buf) - 4) % n
        if pad:
            self.buf += bytes(pad)

    def primitive(self, ftype: str, value: Any) -> None:
        st = _STRUCTS[ftype]
        self._align(st.size)
        try:
            self.buf += st.pack(value)
        except struct.error as exc:
            raise MessageError(f"value {value!r} does not fit a CDR {ftype}: {exc}") from None

    def string(self, value: str) -> None:
        try:
            raw = value.encode()
        except UnicodeEncodeError as exc:
            raise MessageError(f"a string is not Unicode text: {exc}") from None
        self.primitive("uint32", len(raw) + 1)
        self.buf += raw
        self.buf += b"\x00"

    def header(self, stamp_ns: int, frame_id: str) -> None:
        sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
        self.primitive("int32", sec)
        self.primitive("uint32", nanosec)
        self.string(frame_id)

    def value(self, ftype: str, value: Any) -> None:
        if ftype.endswith("[]"):
            self.sequence(ftype[:-2], value)
        elif ftype in _STRUCTS:
            self.primitive(ftype, value)
        elif ftype == "string":
            self.string(value)
        elif ftype == HEADER:
            self.header(*value)
        else:
            self.struct(ftype, value)

    def sequence(self, item: str, values: Any) -> None:
        if item in _DTYPES:
            arr = np.ascontiguousarray(values, dtype=_DTYPES[item])
            self.primitive("uint32", arr.size)
            if arr.size:
                self._align(arr.itemsize)
                self.buf += arr.data.cast("B")
            return
        self.primitive("uint32", len(values))
        if item == "string":
            self._strings(values)
            return
        for v in values:
            self.value(item, v)

    def _strings(self, values: Any) -> None:
        """``string[]`` elements; the bytes of a name list seen before come from :data:`_ENCODED_NAMES`."""
        try:
            key = tuple(values)
            chunk = _ENCODED_NAMES.get(key)
        except TypeError:  # an unhashable element: encoded (and refused) below
            key = chunk = None
        if chunk is None:
            chunk = self._encode_strings(values)
            if key is not None and len(chunk) <= _NAMES_CACHE_BYTES:
                _remember(_ENCODED_NAMES, key, chunk)
        self.buf += chunk

    @staticmethod
    def _encode_strings(values: Any) -> bytes:
        """The elements of a ``string[]`` after its count (which leaves them 4-byte aligned)."""
        buf = bytearray()
        for v in values:
            try:
                raw = v.encode()
            except (AttributeError, UnicodeEncodeError) as exc:
                raise MessageError(f"a string is not Unicode text: {exc}") from None
            pad = -len(buf) % 4
            if pad:
                buf += bytes(pad)
            buf += _U32.pack(len(raw) + 1)
            buf += raw
            buf += b"\x00"
        return bytes(buf)

    def struct(self, ftype: str, values: dict[str, Any]) -> None:
        for t, name in self.specs[ftype]:
            self.value(t, values[name])


class CdrReader:
    """Reads CDR values from a payload, checking every length; raises :class:`MessageError`.

    Each type is read by a plan built once per field list (:func:`_plan`): a tuple of small
    readers, one per field, so no type name is parsed per message.
    """

    def __init__(self, data: bytes | bytearray | memoryview, specs: dict[str, Fields]) -> None:
        self.data = memoryview(data).cast("B") if not isinstance(data, bytes) else memoryview(data)
        self.size = len(self.data)
        self.specs = specs
        if self.size < 4:
            raise MessageError(f"a CDR payload needs a 4-byte encapsulation header, got {self.size} byte(s)")
        if bytes(self.data[:2]) != ENCAPSULATION_LE[:2]:
            raise MessageError(
                f"only little-endian CDR (00 01) is read, got encapsulation {bytes(self.data[:2]).hex()}"
            )
        self.pos = 4

    def take(self, n: int, align: int, what: str) -> int:
        """Start offset of ``n`` bytes after aligning to ``align``; advances past them."""
        start = self.pos + (-(self.pos - 4) % align)
        end = start + n
        if end > self.size:
            raise MessageError(
                f"truncated CDR payload: {what} needs {n} byte(s) at offset {start}, {max(self.size - start, 0)} left"
            )
        self.pos = end
        return start

    def struct(self, ftype: str) -> dict[str, Any]:
        return _plan(self.specs, ftype)(self)

    def finish(self) -> None:
        """No bytes may follow the message except up to 3 bytes of padding."""
        if len(self.data) - self.pos > 3:
            raise MessageError(f"{len(self.data) - self.pos} unexpected byte(s) after the CDR message")


Read = Callable[[CdrReader], Any]


_PLANS: dict[int, tuple[dict[str, Fields], dict[str, Read]]] = {}  # id(specs) → (specs, readers by type)


def _plan(specs: dict[str, Fields], ftype: str) -> Read:
    """The reader of one field type, built on first use for this ``specs`` table."""
    entry = _PLANS.get(id(specs))
    if entry is None or entry[0] is not specs:
        entry = _PLANS[id(specs)] = (specs, {})
    read = entry[1].get(ftype)
    if read is None:
        read = entry[1][ftype] = _build(specs, ftype)
    return read


def _build(specs: dict[str, Fields], ftype: str) -> Read:
    if ftype.endswith("[]"):
        return _sequence_reader(specs, ftype[:-2])
    if ftype in _STRUCTS:
        return _primitive_reader(ftype)
    if ftype == "string":
        return _read_string
    if ftype == HEADER:
        return _read_header
    pairs = tuple((name, _plan(specs, t)) for t, name in specs[ftype])

    def read(r: CdrReader) -> dict[str, Any]:
        return {name: f(r) for name, f in pairs}

    return read


@functools.cache
def _primitive_reader(ftype: str) -> Read:
    st = _STRUCTS[ftype]
    size = st.size
    if ftype == "bool":

        def read_bool(r: CdrReader) -> bool:
            byte = r.data[r.take(1, 1, ftype)]
            if byte > 1:
                raise MessageError(f"a CDR bool must be 0 or 1, got {byte}")
            return bool(byte)

        return read_bool

    def read(r: CdrReader) -> Any:
        return st.unpack_from(r.data, r.take(size, size, ftype))[0]

    return read


_read_uint32 = _primitive_reader("uint32")
_STAMP = struct.Struct("<iI")
_U32 = _STRUCTS["uint32"]


def _read_string(r: CdrReader) -> str:
    n = _read_uint32(r)
    start = r.take(n, 1, "string")
    if n == 0 or r.data[start + n - 1] != 0:
        raise MessageError("a CDR string must end with NUL")
    try:
        return bytes(r.data[start : start + n - 1]).decode()
    except UnicodeDecodeError as exc:
        raise MessageError(f"a CDR string is not UTF-8: {exc}") from None


def _read_strings(r: CdrReader) -> list[str]:
    """``string[]``; a name list whose bytes were read before comes from :data:`_DECODED_NAMES`."""
    n = _read_uint32(r)
    seen = _DECODED_NAMES.get(n)
    if seen is not None:
        raw, names = seen
        end = r.pos + len(raw)
        if end <= r.size and r.data[r.pos : end] == raw:
            r.pos = end
            return list(names)
    start = r.pos
    names = _parse_strings(r, n)
    if r.pos - start <= _NAMES_CACHE_BYTES:
        _remember(_DECODED_NAMES, n, (bytes(r.data[start : r.pos]), tuple(names)))
    return names


def _parse_strings(r: CdrReader, n: int) -> list[str]:
    data, size, pos = r.data, r.size, r.pos
    if n > size - pos:
        raise MessageError(f"truncated CDR payload: {n} string element(s) announced, {size - pos} byte(s) left")
    out = []
    for _ in range(n):
        pos += -(pos - 4) % 4
        if pos + 4 > size:
            raise MessageError(f"truncated CDR payload: a string length needs 4 byte(s) at offset {pos}")
        k = _U32.unpack_from(data, pos)[0]
        pos += 4
        end = pos + k
        if k == 0 or end > size or data[end - 1] != 0:
            raise MessageError(f"a CDR string at offset {pos} must fit the payload and end with NUL")
        try:
            out.append(str(data[pos : end - 1], "utf-8"))
        except UnicodeDecodeError as exc:
            raise MessageError(f"a CDR string is not UTF-8: {exc}") from None
        pos = end
    r.pos = pos
    return out


# Joint names repeat in every message of a topic: the encoded bytes of a name list, and the names
# of the bytes last read for each element count, are kept (lists up to 4 kB, a few dozen entries,
# cleared when full).
_NAMES_CACHE_SIZE = 64
_NAMES_CACHE_BYTES = 4096
_ENCODED_NAMES: dict[tuple, bytes] = {}
_DECODED_NAMES: dict[int, tuple[bytes, tuple[str, ...]]] = {}


def _remember(cache: dict, key: Any, value: Any) -> None:
    if len(cache) >= _NAMES_CACHE_SIZE:
        cache.clear()
    cache[key] = value


def _read_header(r: CdrReader) -> tuple[int, str]:
    sec, nanosec = _STAMP.unpack_from(r.data, r.take(8, 4, "header stamp"))
    if sec < 0 or nanosec >= 1_000_000_000:
        raise MessageError(f"header stamp must be a time ≥ 0 with nanosec < 1e9, got {sec} s {nanosec} ns")
    return sec * 1_000_000_000 + nanosec, _read_string(r)


def _sequence_reader(specs: dict[str, Fields], item: str) -> Read:
    dtype = _DTYPES.get(item)
    if dtype is not None:
        return _array_reader(item, dtype)
    if item == "string":
        return _read_strings
    element = _plan(specs, item)

    def read(r: CdrReader) -> list[Any]:
        n = _read_uint32(r)
        if n > r.size - r.pos:  # every element takes at least one byte
            raise MessageError(f"truncated CDR payload: {n} {item} element(s) announced, {r.size - r.pos} byte(s) left")
        return [element(r) for _ in range(n)]

    return read


@functools.cache
def _array_reader(item: str, dtype: np.dtype) -> Read:
    size = dtype.itemsize

    def read(r: CdrReader) -> np.ndarray:
        n = _read_uint32(r)
        start = r.take(n * size, size if n else 1, f"{item}[{n}]")
        arr = np.frombuffer(r.data, dtype=dtype, count=n, offset=start)
        if item == "bool":
            if n and arr.max() > 1:
                raise MessageError("a CDR bool must be 0 or 1")
            arr = arr.view(np.bool_)
        return arr

    return read
