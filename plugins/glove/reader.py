"""CyberGlove II device reader: bring-up, streaming, arrival timestamps, reconnect (protocol §10–§11).

:class:`GloveReader` runs one thread that owns the link.  It opens the port (pyserial on a serial
or ``/dev/rfcommN`` device, or a direct RFCOMM socket for ``bt://AA:BB:CC:DD:EE:FF[/channel]``
where the OS has ``socket.AF_BLUETOOTH``), stops a running stream (``^C``; bytes still in flight
are parsed, not flushed), checks ``?G`` = 3 and ``?S``, configures timestamp (``D``), status byte
(``U``) and period (``T``), starts ``S`` and frames the stream with
:class:`~handflow.plugins.glove.protocol.StreamParser`.  Every record gets the arrival time from ``clock_ns``
(the node passes ``ctx.now_ns``) and is appended to a thread-safe queue that :meth:`drain` empties.

If no record arrives for ``stall_timeout_s`` the link counts as stalled and is re-initialised; an
I/O error or a vanished device closes the port and reopens it with exponential backoff.  The link
state and counters (records, corrupt, gaps, missed records from the device timestamps, reconnects
…) are read with :meth:`snapshot`.
"""

from __future__ import annotations

import collections
import socket
import threading
import time
from collections.abc import Callable

import serial
from pydantic import Field

from handflow.framework.files.params import StrictModel
from handflow.plugins.hands.sensors import N_SENSORS

from . import protocol as P


class GloveLinkError(RuntimeError):
    """The glove did not answer as expected during bring-up."""


class ReaderConfig(StrictModel):
    """Link and stream settings (documented defaults: 115200 8N1, 100 Hz, timestamp + status on).

    Declared once: the ``glove.cyberglove`` node's parameters extend this model.
    """

    port: str = Field(description="serial device, /dev/rfcommN or bt://AA:BB:CC:DD:EE:FF[/channel]")
    baudrate: int = Field(115200, gt=0)
    glove_rate_hz: float = Field(100.0, gt=0, description="record rate the glove is set to stream (T command)")
    timestamp: bool = Field(True, description="records carry the glove's timestamp")
    status_byte: bool = Field(True, description="records carry the glove's status byte")
    read_timeout_s: float = Field(0.01, gt=0)
    reply_timeout_s: float = Field(0.5, gt=0, description="wait for a command's reply or acknowledgement")
    stop_drain_s: float = Field(0.1, ge=0)
    stall_timeout_s: float = Field(0.5, gt=0, description="no record for this long: the link is reopened")
    backoff_initial_s: float = Field(0.05, gt=0, description="first wait before reopening a lost link")
    backoff_max_s: float = Field(2.0, gt=0, description="longest wait between reopening attempts")


class RfcommTransport:
    """A Bluetooth RFCOMM socket with the small pyserial surface the reader uses."""

    def __init__(self, address: str, channel: int, timeout: float) -> None:
        if not hasattr(socket, "AF_BLUETOOTH"):
            raise GloveLinkError(
                "this Python/OS has no socket.AF_BLUETOOTH; bind the glove to "
                "/dev/rfcommN (rfcomm bind) and use that path as the port"
            )
        self._sock = socket.socket(socket.AF_BLUETOOTH, socket.SOCK_STREAM, socket.BTPROTO_RFCOMM)
        self._sock.connect((address, channel))
        self._sock.settimeout(timeout)

    def read(self, n: int) -> bytes:
        try:
            data = self._sock.recv(n)
        except TimeoutError:
            return b""
        if not data:
            raise OSError("RFCOMM connection closed by the glove")
        return data

    @property
    def in_waiting(self) -> int:
        return 0

    def write(self, data: bytes) -> None:
        self._sock.sendall(data)

    def close(self) -> None:
        self._sock.close()


def open_transport(cfg: ReaderConfig):
    """pyserial port, or :class:`RfcommTransport` for ``bt://ADDRESS[/CHANNEL]``."""
    if cfg.port.startswith("bt://"):
        addr, _, chan = cfg.port[5:].partition("/")
        return RfcommTransport(addr, int(chan or 1), cfg.read_timeout_s)
    return serial.Serial(
        cfg.port,
        cfg.baudrate,
        bytesize=8,
        parity="N",
        stopbits=1,
        xonxoff=False,
        rtscts=False,
        timeout=cfg.read_timeout_s,
        write_timeout=1.0,
    )


class GloveReader:
    """``r = GloveReader(ReaderConfig(port=port)); r.start(); ...; r.drain() -> [(Record, arrival_ns)]``."""

    def __init__(self, cfg: ReaderConfig, clock_ns: Callable[[], int] = time.time_ns) -> None:
        self.cfg = cfg
        self.clock_ns = clock_ns
        self.parser = P.StreamParser(P.RecordFormat(N_SENSORS, cfg.timestamp, cfg.status_byte))
        self.period_words = P.period_words(cfg.glove_rate_hz)
        self.link_state = "stopped"
        self.info = ""
        self.counters = {
            "reconnects": 0,
            "stalls": 0,
            "gaps": 0,
            "missed_records": 0,
            "out_of_order": 0,
            "io_errors": 0,
            "bringup_failures": 0,
        }
        self._queue: collections.deque = collections.deque()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_ticks: int | None = None
        self._lock = threading.Lock()
        self.last_error = ""

    # -- public ----------------------------------------------------------------------------------
    def start(self) -> GloveReader:
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="glove-reader", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread:
            self._thread.join(timeout=5)
        self._set_state("stopped")

    def drain(self) -> list[tuple[P.Record, int]]:
        """All records received since the last call, oldest first, with arrival times (ns)."""
        out = []
        q = self._queue
        while q:
            out.append(q.popleft())
        return out

    def snapshot(self) -> tuple[str, dict[str, float]]:
        """Link state and a copy of all counters (reader + parser)."""
        with self._lock:
            counters = {k: float(v) for k, v in self.counters.items()}
            counters.update(self.parser.counters.as_dict())
            return self.link_state, counters

    # -- link thread -----------------------------------------------------------------------------
    def _set_state(self, state: str) -> None:
        with self._lock:
            self.link_state = state

    def _run(self) -> None:
        backoff = self.cfg.backoff_initial_s
        first = True
        while not self._stop.is_set():
            if not first:
                self.counters["reconnects"] += 1
            first = False
            self._set_state("connecting")
            link = None
            try:
                link = open_transport(self.cfg)
                self._bring_up(link)
                backoff = self.cfg.backoff_initial_s
                self._set_state("streaming")
                self._stream(link)
            except GloveLinkError as exc:
                self.counters["bringup_failures"] += 1
                self.last_error = str(exc)
            except (OSError, serial.SerialException) as exc:
                self.counters["io_errors"] += 1
                self.last_error = str(exc)
            finally:
                if link is not None:
                    self._close(link)
            if self._stop.is_set():
                break
            self._set_state("disconnected")
            self._stop.wait(backoff)
            backoff = min(backoff * 2, self.cfg.backoff_max_s)

    def _close(self, link) -> None:
        try:
            if self._stop.is_set():  # normal shutdown: leave the glove idle
                link.write(P.stop())
            link.close()
        except (OSError, serial.SerialException):
            pass
        self.parser.reset()

    def _read_for(self, link, seconds: float, until: Callable[[bytes], bool] | None = None) -> bytes:
        buf = bytearray()
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline and not self._stop.is_set():
            buf += link.read(max(1, link.in_waiting))
            if until and until(bytes(buf)):
                break
        return bytes(buf)

    def _bring_up(self, link) -> None:
        cfg = self.cfg
        link.write(P.stop())
        # A stream may still be running: parse what is in flight instead of flushing it away.
        self._deliver(self._read_for(link, cfg.stop_drain_s), self.clock_ns())
        self.parser.reset()
        valid = self._query(link, "G")[0]
        if valid != 3:
            raise GloveLinkError(
                f"glove not ready: ?G = {valid} (3 = initialised and connected); check the glove cable"
            )
        n = self._query(link, "S")[0]
        if n != N_SENSORS:
            raise GloveLinkError(f"glove reports {n} sensors; this reader supports the 22-sensor CyberGlove II")
        self._set(link, "D", P.set_flag("D", cfg.timestamp))
        self._set(link, "U", P.set_flag("U", cfg.status_byte))
        self._set(link, "T", P.set_period(*self.period_words))
        link.write(P.start_stream())  # device-time gap tracking continues across reconnects

    def _query(self, link, letter: str) -> bytes:
        link.write(P.query(letter))
        buf = self._read_for(link, self.cfg.reply_timeout_s, lambda b: P.parse_query_reply(letter, b) is not None)
        found = P.parse_query_reply(letter, buf)
        if found is None:
            raise GloveLinkError(f"no reply to ?{letter} within {self.cfg.reply_timeout_s} s (got {buf[:32]!r})")
        return found[0]

    def _set(self, link, letter: str, command: bytes) -> None:
        link.write(command)
        buf = self._read_for(link, self.cfg.reply_timeout_s, lambda b: P.parse_ack(letter, b) is not None)
        if P.parse_ack(letter, buf) is None:
            raise GloveLinkError(
                f"no acknowledgement of '{letter}' within {self.cfg.reply_timeout_s} s (got {buf[:32]!r})"
            )

    def _stream(self, link) -> None:
        last_record = time.monotonic()
        while not self._stop.is_set():
            chunk = link.read(max(1, link.in_waiting))
            now = time.monotonic()
            if chunk and self._deliver(chunk, self.clock_ns()):
                last_record = now
            elif now - last_record > self.cfg.stall_timeout_s:
                self.counters["stalls"] += 1
                self._set_state("stalled")
                raise GloveLinkError(f"no record for {self.cfg.stall_timeout_s} s (stalled stream)")

    def _deliver(self, chunk: bytes, arrival_ns: int) -> int:
        records = self.parser.feed(chunk)
        period = self.period_words[0] * self.period_words[1]
        for rec in records:
            if rec.device_time is not None:
                self._check_gap(rec.device_time, period)
            self._queue.append((rec, arrival_ns))
        return len(records)

    def _check_gap(self, ticks: int, period: int) -> None:
        last, self._last_ticks = self._last_ticks, ticks
        if last is None:
            return
        delta = (ticks - last) & 0xFFFFFFFF
        if delta == 0 or delta > 0x7FFFFFFF:
            self.counters["out_of_order"] += 1
        elif delta > 1.5 * period:
            self.counters["gaps"] += 1
            self.counters["missed_records"] += round(delta / period) - 1
