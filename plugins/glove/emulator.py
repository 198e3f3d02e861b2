"""A CyberGlove II on a pseudo-terminal that answers byte for byte (reference cyberglove-protocol.md §13).

:class:`GloveEmulator` opens a pty pair (``os.openpty``) and exposes a *stable* path (a symlink to
the pty slave, like a udev name for a USB-serial adapter) so a reader can reopen it after a
simulated disconnect.  A thread answers the binary commands a driver uses (``^C``, ``S``, ``G``,
``?X`` queries, one-byte/3-byte/4-byte set commands with ``letter NUL`` acks, ``^R``, ``^I``,
``e?`` for unknown bytes) and, while streaming, writes records on an absolute clock (no drift).
While streaming only ``^C`` is accepted (§8).  Baud is nominal on a pty.

An RFCOMM-like link (§13.1) is emulated with ``burst`` (1…burst records coalesced per write) and
``jitter_s`` (each write up to that late).

Record values come from a pluggable source ``source(k, t) -> 22 values``.  The record's 32-bit
timestamp (115200 Hz ticks since power-up, ``D`` flag) gives every record an identity that tests
check for loss, duplication and order.

Fault injection (seeded, scheduled by record number, every injection logged in ``faults`` and the
damaged records' timestamps in ``damaged``): ``garbage`` (random bytes incl. fake leads and NULs
between two records), ``drop_bytes``, ``truncate``, ``zero_value``, ``disconnect`` (the pty
vanishes mid-record and reappears after ``duration_s``; streaming has stopped, settings kept) and
``stall`` (the glove hangs mid-record for ``duration_s``: no output, commands wait; the records
of that time are never produced).  ``sent`` holds every streamed record started; the records a
fault damaged (possibly still readable, e.g. after a short stall) are in ``damaged``.
"""

from __future__ import annotations

import collections
import os
import select
import shutil
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from handflow.plugins.hands.sensors import MASK22, N_SENSORS

from . import protocol as P

Source = Callable[[int, float], np.ndarray]
"""Record values for record number ``k`` at emulator time ``t`` seconds."""

FaultKind = Literal["garbage", "drop_bytes", "truncate", "zero_value", "disconnect", "stall"]


@dataclass
class Fault:
    """One scheduled fault, applied when streamed record number ``at_record`` is due."""

    kind: FaultKind
    at_record: int
    size: int = 8
    duration_s: float = 0.3


@dataclass
class GloveState:
    """Power-up defaults of the CGIU (§13.2); ``period`` is configurable (real default unknown)."""

    period: tuple[int, int] = (1152, 1)
    timestamp: bool = False
    status_byte: bool = False
    filter: bool = True
    switch_light: bool = True
    light: bool = False
    quantized: bool = False
    mask: int = MASK22
    n_values: int = N_SENSORS
    right_hand: bool = True
    streaming: bool = False

    def record_format(self, lead: int = P.LEAD_STREAM) -> P.RecordFormat:
        return P.RecordFormat(self.n_values, self.timestamp, self.status_byte, lead)


def constant_source(value: int = 100) -> Source:
    """All sensors at ``value``."""
    frame = np.full(N_SENSORS, value, dtype=np.int64)
    return lambda k, t: frame


def array_source(frames: np.ndarray) -> Source:
    """Replay raw frames (n × 22), looping."""
    frames = np.asarray(frames, dtype=np.int64)
    if frames.ndim != 2 or frames.shape[1] != N_SENSORS or len(frames) == 0:
        raise ValueError(f"raw frames must be an (n, {N_SENSORS}) array with n ≥ 1, got shape {frames.shape}")
    return lambda k, t: frames[k % len(frames)]


class GloveEmulator:
    """``with GloveEmulator(source) as emu: Serial(emu.path)`` — a glove on a pty.

    ``period`` sets the power-up ``T`` (the reader normally sets its own rate); ``reset_delay_s`` is
    the ^R reboot time (§3, ~1.75 s).  ``sent`` lists ``(record number, timestamp)`` of every
    streamed record started (the last ``log_limit``); ``damaged`` holds the timestamps of records a fault broke.
    """

    def __init__(
        self,
        source: Source | None = None,
        *,
        period: tuple[int, int] = (1152, 1),
        faults: list[Fault] | None = None,
        seed: int = 0,
        reset_delay_s: float = 1.75,
        link_dir: str | Path | None = None,
        log_limit: int = 1_000_000,
        burst: int = 1,
        jitter_s: float = 0.0,
    ) -> None:
        self.source = source or constant_source()
        self.faults = sorted(faults or [], key=lambda f: f.at_record)
        self.rng = np.random.default_rng(seed)
        self.reset_delay_s = reset_delay_s
        self._defaults = GloveState(period=period)
        self.state = GloveState(period=period)
        self._own_dir = link_dir is None
        self._dir = Path(link_dir) if link_dir else Path(tempfile.mkdtemp(prefix="handflow-glove-"))
        self.path = str(self._dir / "ttyCyberGlove")
        self.sent: collections.deque[tuple[int, int]] = collections.deque(maxlen=log_limit)
        self.damaged: set[int] = set()
        self.fault_log: list[dict] = []
        self.counters = {"records": 0, "commands": 0, "unknown_commands": 0, "faults": 0, "opens": 0}
        self._master = self._slave = -1
        self._inbuf = bytearray()
        self._record_no = 0
        self._next_due = 0.0
        self.burst, self.jitter_s = max(1, burst), jitter_s
        self._pending: list[bytes] = []
        self._burst_target = 1
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._t0 = time.monotonic()

    # -- lifecycle -------------------------------------------------------------------------------
    def start(self) -> GloveEmulator:
        self._open_pty()
        self._thread = threading.Thread(target=self._run, name="glove-emulator", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread:
            self._thread.join(timeout=5)
        self._close_pty()
        if self._own_dir:
            shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self) -> GloveEmulator:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    @property
    def record_period_s(self) -> float:
        return P.period_s(*self.state.period)

    def ticks(self, t: float | None = None) -> int:
        """The CGIU tick counter (115200 Hz since start), 32 bit."""
        t = time.monotonic() if t is None else t
        return int((t - self._t0) * P.TICK_HZ) & 0xFFFFFFFF

    def _open_pty(self) -> None:
        if not hasattr(os, "openpty"):
            raise RuntimeError(
                "the glove emulator needs pseudo-terminals (POSIX: Linux or macOS); "
                "on this platform connect a real glove with 'port: <serial device>'"
            )
        import tty

        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        tmp = self.path + ".new"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(os.ttyname(self._slave), tmp)
        os.replace(tmp, self.path)
        self.counters["opens"] += 1

    def _close_pty(self) -> None:
        if os.path.lexists(self.path):
            os.unlink(self.path)
        for fd in (self._master, self._slave):
            if fd >= 0:
                os.close(fd)
        self._master = self._slave = -1

    # -- main loop -------------------------------------------------------------------------------
    def _run(self) -> None:
        while not self._stop.is_set():
            now = time.monotonic()
            wait = max(0.0, self._next_due - now) if self.state.streaming else 0.05
            ready, _, _ = select.select([self._master], [], [], min(wait, 0.05))
            if ready:
                self._read_commands()
            while self.state.streaming and time.monotonic() >= self._next_due and not self._stop.is_set():
                self._emit_streamed()
                self._next_due += self.record_period_s

    def _read_commands(self) -> None:
        try:
            data = os.read(self._master, 4096)
        except OSError:  # nothing pending, or no reader attached
            data = b""
        if data:
            self._inbuf += data
            self._handle_commands()

    def _queue_record(self, record: bytes) -> None:
        """RFCOMM-like delivery: coalesce 1…``burst`` records per write, each write up to ``jitter_s`` late."""
        self._pending.append(record)
        if len(self._pending) >= self._burst_target:
            if self.jitter_s:
                self._sleep(float(self.rng.uniform(0.0, self.jitter_s)))
            self._write(b"")
            self._burst_target = int(self.rng.integers(1, self.burst + 1))

    def _write(self, data: bytes) -> None:
        """Write queued records, then ``data`` — all of it (a glove's UART does not drop bytes); waits
        while the pty buffer is full."""
        data = b"".join(self._pending) + data
        self._pending.clear()
        view = memoryview(data)
        while view and not self._stop.is_set():
            try:
                n = os.write(self._master, view)
                view = view[n:]
            except BlockingIOError:
                select.select([], [self._master], [], 0.05)

    # -- commands --------------------------------------------------------------------------------
    def _handle_commands(self) -> None:
        buf = self._inbuf
        while buf:
            c = buf[0]
            if self.state.streaming:  # only ^C is accepted while streaming
                del buf[0]
                if c == P.CTRL_C:
                    self.state.streaming = False
                    self._write(b"")  # records already coalesced still go out
                    self.counters["commands"] += 1
                continue
            letter = chr(c)
            if c == P.CTRL_C:
                del buf[0]
            elif letter == "S":
                del buf[0]
                self.state.streaming = True
                self._next_due = time.monotonic() + self.record_period_s
            elif letter == "G":
                del buf[0]
                fmt = self.state.record_format(P.LEAD_POLL)
                self._write(
                    P.encode_record(self.source(self._record_no, self._now()), fmt, self.ticks(), self._status())
                )
            elif letter == "?":
                if len(buf) < 2:
                    return
                self._write(self._query(chr(buf[1])))
                del buf[:2]
            elif letter in P.SET_ARG_LEN:
                n = P.SET_ARG_LEN[letter]
                if len(buf) < 1 + n:
                    return
                self._set(letter, bytes(buf[1 : 1 + n]))
                del buf[: 1 + n]
                self._write(letter.encode() + b"\x00")
            elif c == 0x12:
                del buf[0]
                self._sleep(self.reset_delay_s)
                self.state = GloveState(period=self._defaults.period)
                self._write(b"\x12\r\n\x00")
            elif c == 0x09:
                del buf[0]
                self._write(b"\x09\r\n\x00")
            else:
                del buf[0]
                self.counters["unknown_commands"] += 1
                self._write(b"e?\x00")
            self.counters["commands"] += 1

    def _status(self) -> int:
        s = self.state
        return 0x80 | 0x01 | (0x04 if s.light else 0)

    def _query(self, letter: str) -> bytes:
        s = self.state
        if letter == "i":
            return b"?iCyberGlove II emulator (handflow)\r\n22 sensors, right hand\r\n\x00"
        payloads = {
            "G": bytes([3]),
            "S": bytes([N_SENSORS]),
            "K": MASK22.to_bytes(3, "little"),
            "M": s.mask.to_bytes(3, "little"),
            "N": bytes([s.n_values]),
            "R": bytes([int(s.right_hand)]),
            "T": s.period[0].to_bytes(2, "big") + s.period[1].to_bytes(2, "big"),
            "U": bytes([int(s.status_byte)]),
            "D": bytes([int(s.timestamp)]),
            "F": bytes([int(s.filter)]),
            "J": bytes([int(s.switch_light)]),
            "L": bytes([int(s.light)]),
            "Q": bytes([int(s.quantized)]),
            "W": bytes([0]),
            "B": bytes([0]),
            "Y": bytes([0]),
            "P": bytes(
                [
                    self._status(),
                    0x80
                    | 0x40 * s.right_hand
                    | 0x20 * s.timestamp
                    | 0x10 * s.filter
                    | 0x08 * s.switch_light
                    | 0x04 * s.status_byte,
                    int(s.quantized),
                ]
            ),
        }
        if letter not in payloads:
            self.counters["unknown_commands"] += 1
            return b"e?\x00"
        return b"?" + letter.encode() + payloads[letter] + b"\x00"

    def _set(self, letter: str, arg: bytes) -> None:
        s = self.state
        if letter == "T":
            s.period = (int.from_bytes(arg[:2], "big"), int.from_bytes(arg[2:], "big"))
        elif letter == "M":
            s.mask = int.from_bytes(arg, "little") & MASK22
        elif letter == "N":
            s.n_values = min(arg[0], N_SENSORS)
        else:
            attr = {
                "D": "timestamp",
                "U": "status_byte",
                "F": "filter",
                "J": "switch_light",
                "L": "light",
                "Q": "quantized",
            }.get(letter)
            if attr:
                setattr(s, attr, bool(arg[0]))

    # -- streaming and faults --------------------------------------------------------------------
    def _now(self) -> float:
        return time.monotonic() - self._t0

    def _emit_streamed(self) -> None:
        k = self._record_no
        self._record_no += 1
        ticks = self.ticks(self._next_due)
        record = P.encode_record(self.source(k, self._now()), self.state.record_format(), ticks, self._status())
        while self.faults and self.faults[0].at_record <= k:
            fault = self.faults.pop(0)
            record = self._inject(fault, k, ticks, record)
            if record is None:
                break
        if record is not None:
            self._queue_record(record)
        self.sent.append((k, ticks))
        self.counters["records"] += 1

    def _inject(self, fault: Fault, k: int, ticks: int, record: bytes) -> bytes | None:
        """Apply ``fault`` to record ``k``; returns the bytes to write (None: nothing more to write)."""
        self.counters["faults"] += 1
        self.fault_log.append({"kind": fault.kind, "record": k, "ticks": ticks, "size": fault.size})
        rng = self.rng
        if fault.kind == "garbage":
            junk = rng.integers(0, 256, fault.size, dtype=np.uint8)
            junk[rng.integers(0, fault.size)] = P.LEAD_STREAM  # fake lead bytes and NULs
            if fault.size > 2:
                junk[rng.integers(0, fault.size)] = P.NUL
            return junk.tobytes() + record
        self.damaged.add(ticks)
        if fault.kind == "drop_bytes":
            at = int(rng.integers(1, len(record) - fault.size + 1))
            return record[:at] + record[at + fault.size :]
        if fault.kind == "truncate":
            return record[: int(rng.integers(1, len(record) - 1))]
        if fault.kind == "zero_value":
            at = int(rng.integers(1, 1 + self.state.n_values))
            return record[:at] + b"\x00" + record[at + 1 :]
        if fault.kind == "disconnect":
            self._write(record[: len(record) // 2])
            self._close_pty()
            self.state.streaming = False
            self._sleep(fault.duration_s)
            self._inbuf.clear()
            self._open_pty()
            return None
        # stall: the glove hangs mid-record; records of that time are never produced, commands wait
        half = len(record) // 2
        self._write(record[:half])
        self._sleep(fault.duration_s)
        self._read_commands()
        self._next_due = time.monotonic()
        return record[half:]

    def _sleep(self, seconds: float) -> None:
        self._stop.wait(seconds)
