"""CyberGlove II binary (CGIU) protocol, pure and I/O-free (reference cyberglove-protocol.md §2–§10).

- command encoders (``stop()``, ``start_stream()``, ``query("G")``, ``set_period(1152, 1)`` …);
- :class:`RecordFormat` and :func:`encode_record` (used by the emulator and by golden tests);
- :class:`StreamParser`: incremental framing of streamed records with resynchronisation and
  counters.  It never blocks: ``feed(chunk)`` returns the complete records found so far.

Framing (§10 "Recommended framing"): split on NUL; a frame is a record only if it starts with the
expected lead byte and has the configured length (plus 0–2 ``e`` error pairs).  A frame that is
too long but *ends* with a valid record (garbage before a record, or a record whose NUL was lost)
yields that record; the rest is counted as corrupt.  So at most the damaged record is lost.

Documented choices: the ``T`` words are sent big-endian (§14 item 5, probable); a zero timestamp
byte is sent as 0x01 with its flag bit set and decoded to 0 (§6.1, works with VTI and VISTA);
the status byte must have bit 7 set (§6.2); bit 7 of the timestamp flag byte is not required
(§14 item 7).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

NUL = 0x00
CTRL_C = 0x03
LEAD_STREAM = ord("S")
LEAD_POLL = ord("G")
TICK_HZ = 115200
"""CGIU clock: the timestamp counter and the ``T`` period count at 115200 Hz."""

QUERY_PAYLOAD = {
    "B": 1,
    "D": 1,
    "F": 1,
    "G": 1,
    "J": 1,
    "K": 3,
    "L": 1,
    "M": 3,
    "N": 1,
    "P": 3,
    "Q": 1,
    "R": 1,
    "S": 1,
    "T": 4,
    "U": 1,
    "W": 1,
    "Y": 1,
}
"""Payload length of the binary query replies ``? X payload NUL`` (§3, §4)."""

SET_ARG_LEN = {"B": 1, "D": 1, "F": 1, "J": 1, "L": 1, "M": 3, "N": 1, "P": 3, "Q": 1, "T": 4, "U": 1, "W": 1, "Y": 1}
"""Argument length of the binary set commands (§4); each is acknowledged with ``letter NUL``."""

ERROR_CODES = {ord("s"): "sample_rate", ord("g"): "glove_unplugged"}
"""In-record error pairs ``e`` + code (§5)."""


# ------------------------------------------------------------------------------------------------
# Commands
# ------------------------------------------------------------------------------------------------
def stop() -> bytes:
    """^C: stop streaming."""
    return bytes([CTRL_C])


def start_stream() -> bytes:
    return b"S"


def poll() -> bytes:
    return b"G"


def query(letter: str) -> bytes:
    """``?X``; reply is ``? X`` + ``QUERY_PAYLOAD[X]`` bytes + NUL."""
    if letter not in QUERY_PAYLOAD:
        raise ValueError(f"no binary query '?{letter}'; known: {''.join(sorted(QUERY_PAYLOAD))}")
    return b"?" + letter.encode()


def set_flag(letter: str, on: bool) -> bytes:
    """One-byte 0/1 set command (``D`` timestamp, ``U`` status byte, ``F`` filter, ``L`` light …)."""
    if SET_ARG_LEN.get(letter) != 1:
        raise ValueError(f"'{letter}' is not a one-byte set command")
    return letter.encode() + bytes([1 if on else 0])


def set_period(w1: int, w2: int) -> bytes:
    """``T w1 w2``: sample period = w1·w2/115200 s (words big-endian, documented choice §14.5)."""
    if not (0 <= w1 < 65536 and 0 <= w2 < 65536):
        raise ValueError(f"period words must be 0..65535, got ({w1}, {w2})")
    return b"T" + w1.to_bytes(2, "big") + w2.to_bytes(2, "big")


def set_mask(mask: int) -> bytes:
    """``M`` + 3 bytes LSB first: software sensor mask (§7)."""
    return b"M" + mask.to_bytes(3, "little")


def period_words(rate_hz: float) -> tuple[int, int]:
    """``T`` words for a sample rate: (round(115200 / rate), 1), or w2 > 1 when w1 overflows."""
    ticks = max(1, round(TICK_HZ / rate_hz))
    w2 = 1 + (ticks - 1) // 65535
    return round(ticks / w2), w2


def period_s(w1: int, w2: int) -> float:
    return w1 * w2 / TICK_HZ


# ------------------------------------------------------------------------------------------------
# Records
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RecordFormat:
    """Shape of a data record: number of values, optional timestamp (D) and status byte (U)."""

    n_values: int = 22
    timestamp: bool = False
    status: bool = False
    lead: int = LEAD_STREAM
    extra_tail: int = 0
    """Unexplained bytes before the NUL (SHADOW 2018 quirk, §5): accepted and ignored."""

    @property
    def length(self) -> int:
        """Bytes before the NUL without error pairs."""
        return 1 + self.n_values + 5 * self.timestamp + self.status + self.extra_tail


@dataclass
class Record:
    """One parsed record: sensor values, optional device tick counter and status, error codes."""

    values: np.ndarray
    device_time: int | None = None
    status: int | None = None
    errors: tuple[str, ...] = ()


def encode_timestamp(ticks: int) -> bytes:
    """5 bytes: flag byte (bit 7 set, bit k = counter byte k was 0) + 4 counter bytes LSB first."""
    raw = (ticks & 0xFFFFFFFF).to_bytes(4, "little")
    flag = 0x80 | sum(1 << k for k, b in enumerate(raw) if b == 0)
    return bytes([flag]) + bytes(b if b else 1 for b in raw)


def decode_timestamp(five: bytes) -> int:
    flag = five[0]
    raw = bytes(0 if flag & (1 << k) else b for k, b in enumerate(five[1:5]))
    return int.from_bytes(raw, "little")


def encode_record(
    values: np.ndarray, fmt: RecordFormat, device_time: int = 0, status: int = 0x81, errors: tuple[str, ...] = ()
) -> bytes:
    """Wire bytes of a record incl. the NUL; values are clamped to 1…255 (0 is the terminator)."""
    vals = np.clip(np.asarray(values, dtype=np.int64), 1, 255).astype(np.uint8)
    if vals.size != fmt.n_values:
        raise ValueError(f"record needs {fmt.n_values} values, got {vals.size}")
    out = bytearray([fmt.lead]) + vals.tobytes()
    if fmt.timestamp:
        out += encode_timestamp(device_time)
    if fmt.status:
        out.append(status | 0x80)
    out += bytes(fmt.extra_tail * [0x7F])
    codes = {v: k for k, v in ERROR_CODES.items()}
    for e in errors:
        out += bytes([ord("e"), codes[e]])
    out.append(NUL)
    return bytes(out)


@dataclass
class ParserCounters:
    """What the parser has seen; ``corrupt`` counts rejected non-empty frames."""

    records: int = 0
    corrupt: int = 0
    salvaged: int = 0
    garbage_bytes: int = 0
    error_pairs: int = 0

    def as_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in self.__dict__.items()}


@dataclass
class StreamParser:
    """Incremental record framer: ``records = parser.feed(chunk)``; never blocks, keeps a partial tail."""

    fmt: RecordFormat = field(default_factory=RecordFormat)
    max_buffer: int = 4096
    counters: ParserCounters = field(default_factory=ParserCounters)

    def __post_init__(self) -> None:
        self._buf = bytearray()

    def reset(self) -> None:
        """Forget a partial frame (after a reconnect); the discarded bytes count as garbage."""
        self.counters.garbage_bytes += len(self._buf)
        self._buf.clear()

    def feed(self, chunk: bytes) -> list[Record]:
        self._buf += chunk
        *frames, rest = self._buf.split(b"\x00")
        self._buf = bytearray(rest)
        if len(self._buf) > self.max_buffer:  # no NUL for far too long: drop, resync on next NUL
            self.counters.garbage_bytes += len(self._buf)
            self._buf.clear()
        out = []
        for frame in frames:
            rec = self._frame(bytes(frame))
            if rec is not None:
                out.append(rec)
        return out

    def _frame(self, frame: bytes) -> Record | None:
        if not frame:
            return None
        rec = self._decode(frame)
        if rec is not None:
            self.counters.records += 1
            return rec
        # Salvage: a valid record at the end of an overlong frame (garbage or lost NUL before it).
        base = self.fmt.length
        for extra in (0, 2, 4):
            n = base + extra
            if len(frame) > n and frame[-n] == self.fmt.lead:
                rec = self._decode(frame[-n:])
                if rec is not None:
                    self.counters.records += 1
                    self.counters.salvaged += 1
                    self.counters.corrupt += 1
                    self.counters.garbage_bytes += len(frame) - n
                    return rec
        self.counters.corrupt += 1
        self.counters.garbage_bytes += len(frame)
        return None

    def _decode(self, frame: bytes) -> Record | None:
        fmt = self.fmt
        extra = len(frame) - fmt.length
        if frame[0] != fmt.lead or extra not in (0, 2, 4):
            return None
        errors = []
        for k in range(fmt.length, len(frame), 2):
            code = ERROR_CODES.get(frame[k + 1])
            if frame[k] != ord("e") or code is None:
                return None
            errors.append(code)
        pos = 1 + fmt.n_values
        values = np.frombuffer(frame, dtype=np.uint8, count=fmt.n_values, offset=1).astype(np.int64)
        device_time = None
        if fmt.timestamp:
            device_time = decode_timestamp(frame[pos : pos + 5])
            pos += 5
        status = None
        if fmt.status:
            status = frame[pos]
            if not status & 0x80:
                return None
        self.counters.error_pairs += len(errors)
        return Record(values, device_time, status, tuple(errors))


def parse_query_reply(letter: str, buf: bytes) -> tuple[bytes, int] | None:
    """Find the reply to ``?letter`` in ``buf`` (junk before it ignored): (payload, end index) or None."""
    head = b"?" + letter.encode()
    n = QUERY_PAYLOAD[letter]
    start = buf.find(head)
    while start >= 0:
        end = start + 2 + n
        if len(buf) <= end:
            return None
        if buf[end] == NUL:
            return bytes(buf[start + 2 : end]), end + 1
        start = buf.find(head, start + 1)
    return None


def parse_ack(letter: str, buf: bytes) -> int | None:
    """End index of the ``letter NUL`` acknowledgement of a set command in ``buf``, or None."""
    i = buf.find(letter.encode() + b"\x00")
    return None if i < 0 else i + 2
