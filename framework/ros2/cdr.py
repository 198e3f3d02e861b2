"""CDR (XCDR1, little-endian, with the 4-byte encapsulation header) reader and writer driven by ``.msg`` field lists.

The layout rules are those of ROS 2 (rmw_fastrtps/rmw_zenoh): primitives aligned to their size
relative to the byte after the encapsulation header, strings as ``uint32`` length (with the NUL) +
bytes + NUL, sequences as ``uint32`` count + elements.  The reader checks every length against the
bytes left, so a malformed payload raises :class:`MessageError` and never reads past the end;
numeric sequences come back as read-only numpy views of the payload (no copy).  Cross-checked
against ``rosbags`` in tests/framework/test_ros2_cdr.py; docs/ros2.md.
"""

from __future__ import annotations

import struct
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
        for v in values:
            self.value(item, v)

    def struct(self, ftype: str, values: dict[str, Any]) -> None:
        for t, name in self.specs[ftype]:
            self.value(t, values[name])


class CdrReader:
    """Reads CDR values from a payload, checking every length; raises :class:`MessageError`."""

    def __init__(self, data: bytes | bytearray | memoryview, specs: dict[str, Fields]) -> None:
        self.data = memoryview(data).cast("B") if not isinstance(data, bytes) else memoryview(data)
        self.specs = specs
        if len(self.data) < 4:
            raise MessageError(f"a CDR payload needs a 4-byte encapsulation header, got {len(self.data)} byte(s)")
        if bytes(self.data[:2]) != ENCAPSULATION_LE[:2]:
            raise MessageError(
                f"only little-endian CDR (00 01) is read, got encapsulation {bytes(self.data[:2]).hex()}"
            )
        self.pos = 4

    def _take(self, n: int, what: str) -> memoryview:
        end = self.pos + n
        if end > len(self.data):
            raise MessageError(
                f"truncated CDR payload: {what} needs {n} byte(s) at offset {self.pos}, {len(self.data) - self.pos} left"
            )
        out = self.data[self.pos : end]
        self.pos = end
        return out

    def _align(self, n: int) -> None:
        self.pos += -(self.pos - 4) % n

    def primitive(self, ftype: str) -> Any:
        st = _STRUCTS[ftype]
        self._align(st.size)
        value = st.unpack(self._take(st.size, ftype))[0]
        if ftype == "bool" and self.data[self.pos - 1] > 1:
            raise MessageError(f"a CDR bool must be 0 or 1, got {self.data[self.pos - 1]}")
        return value

    def string(self) -> str:
        n = self.primitive("uint32")
        raw = self._take(n, "string")
        if n == 0 or raw[-1] != 0:
            raise MessageError("a CDR string must end with NUL")
        try:
            return bytes(raw[:-1]).decode()
        except UnicodeDecodeError as exc:
            raise MessageError(f"a CDR string is not UTF-8: {exc}") from None

    def header(self) -> tuple[int, str]:
        sec, nanosec = self.primitive("int32"), self.primitive("uint32")
        if sec < 0 or nanosec >= 1_000_000_000:
            raise MessageError(f"header stamp must be a time ≥ 0 with nanosec < 1e9, got {sec} s {nanosec} ns")
        return sec * 1_000_000_000 + nanosec, self.string()

    def value(self, ftype: str) -> Any:
        if ftype.endswith("[]"):
            return self.sequence(ftype[:-2])
        if ftype in _STRUCTS:
            return self.primitive(ftype)
        if ftype == "string":
            return self.string()
        if ftype == HEADER:
            return self.header()
        return self.struct(ftype)

    def sequence(self, item: str) -> Any:
        n = self.primitive("uint32")
        dtype = _DTYPES.get(item)
        if dtype is not None:
            if n:
                self._align(dtype.itemsize)
            raw = self._take(n * dtype.itemsize, f"{item}[{n}]")
            arr = np.frombuffer(raw, dtype=dtype)
            if item == "bool":
                if arr.size and arr.max() > 1:
                    raise MessageError("a CDR bool must be 0 or 1")
                arr = arr.view(np.bool_)
            return arr
        if n > len(self.data) - self.pos:  # every element takes at least one byte
            raise MessageError(
                f"truncated CDR payload: {n} {item} element(s) announced, {len(self.data) - self.pos} byte(s) left"
            )
        return [self.value(item) for _ in range(n)]

    def struct(self, ftype: str) -> dict[str, Any]:
        return {name: self.value(t) for t, name in self.specs[ftype]}

    def finish(self) -> None:
        """No bytes may follow the message except up to 3 bytes of padding."""
        if len(self.data) - self.pos > 3:
            raise MessageError(f"{len(self.data) - self.pos} unexpected byte(s) after the CDR message")
