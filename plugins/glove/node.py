"""``glove.cyberglove``: CyberGlove II reader node (thin wrapper of :class:`~handflow.plugins.glove.reader.GloveReader`).

The reader thread timestamps records on arrival (``ctx.now_ns``) and queues them; the node drains
the queue in ``tick()`` (``rate_hz``, default 500 Hz) and publishes every record on ``frames``
(stamp = arrival time) — all publishing happens on the node's thread.  ``status`` carries the link
state (``ok`` streaming, ``warn`` connecting/stalled, ``error`` disconnected) with the counters,
on every change and every ``status_period_s``.

``port: emulator`` starts an embedded :class:`~handflow.plugins.glove.emulator.GloveEmulator` (source:
the synthetic hand motion, or ``emulator.frames`` = a .npy/.csv/.mcap file of raw frames), so a
graph runs without hardware and without a second command.
"""

from __future__ import annotations

import glob
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field

from handflow.framework.files.inputs import InputFile, InputPath
from handflow.framework.files.params import StrictModel
from handflow.framework.messages import GloveFrame, Status
from handflow.framework.plugin import Node

from .emulator import Fault, GloveEmulator, array_source
from .frames_io import load_frames
from .reader import GloveReader, ReaderConfig, open_transport
from .synthetic import HandMotion, SyntheticGlove


class FaultParams(StrictModel):
    kind: Literal["garbage", "drop_bytes", "truncate", "zero_value", "disconnect", "stall"]
    at_record: int
    size: int = 8
    duration_s: float = 0.3


class EmulatorParams(StrictModel):
    """Options of the embedded emulator (``port: emulator``)."""

    frames: InputFile | None = Field(
        None, description="raw frames file (.npy/.csv/.mcap) to loop; default: synthetic motion"
    )
    motion_period_s: float = 4.0
    noise: float = 0.5
    seed: int = 0
    burst: int = Field(1, ge=1, description="RFCOMM-like: coalesce 1..burst records per write")
    jitter_s: float = Field(0.0, ge=0, description="RFCOMM-like: each write up to this late")
    faults: list[FaultParams] = Field(default_factory=list)


RUNNING_LOG_LIMIT = 1000  # records of the emulator's ``sent`` log kept in a graph or by glove-emulator


def build_emulator(
    opts: EmulatorParams, resolve=lambda p: p, log_limit: int = RUNNING_LOG_LIMIT, source=None
) -> GloveEmulator:
    """An emulator from options (used by the node and by ``handflow glove-emulator``); ``source``
    replaces the one the options name (a node that makes its own frames).

    Both run for hours and read no record log, so it keeps only the last ``log_limit`` records
    (a log of every record grew the node's memory by about 24 MB an hour at 50 Hz)."""
    if source is None and opts.frames:
        source = array_source(load_frames(resolve(opts.frames)))
    elif source is None:
        source = SyntheticGlove(
            HandMotion(opts.motion_period_s, seed=opts.seed), noise=opts.noise, seed=opts.seed
        ).source
    faults = [Fault(f.kind, f.at_record, f.size, f.duration_s) for f in opts.faults]
    return GloveEmulator(
        source, faults=faults, seed=opts.seed, burst=opts.burst, jitter_s=opts.jitter_s, log_limit=log_limit
    )


def serial_ports() -> list[str]:
    """Serial devices on this machine (pyserial's list plus Bluetooth ``/dev/rfcomm*`` bindings)."""
    from serial.tools import list_ports

    return sorted({p.device for p in list_ports.comports()} | set(glob.glob("/dev/rfcomm*")))


def _no_device(port: str) -> bool:
    """True for port values that name no device file."""
    return port == "emulator" or port.startswith("bt://")


DEVICE_HINT = (
    "plug the glove in or pair it (Bluetooth: /dev/rfcommN), set 'port' to its device "
    "(`python -m serial.tools.list_ports` lists them), or use 'port: emulator' to run without hardware"
)
GLOVE_PORT = InputPath("device", "glove device", DEVICE_HINT, skip=_no_device)


def missing_device_message(port: str) -> str | None:
    """What to do when ``port`` names a serial device that does not exist (None if it exists or is not a path)."""
    if _no_device(port) or Path(port).exists():
        return None
    found = ", ".join(serial_ports()) or "none"
    return f"glove device {port} not found (serial ports on this machine: {found}); {DEVICE_HINT}"


def unusable_device_message(port: str) -> str | None:
    """What to do when ``port`` names a device that is missing or cannot be opened and configured as a
    serial port, /dev/null say (None if it can be, or is no path); opens and closes it once."""
    if _no_device(port):
        return None
    if (problem := missing_device_message(port)) is not None:
        return problem
    try:
        open_transport(ReaderConfig(port=port)).close()
    except OSError as exc:  # pyserial's SerialException is one
        found = ", ".join(serial_ports()) or "none"
        return (
            f"glove device {port} cannot be opened as a serial port ({exc}); check that it is the glove's "
            f"device (serial ports on this machine: {found}) and that you may open it (group dialout); {DEVICE_HINT}"
        )
    return None


class CyberGloveNode(Node):
    """CyberGlove II reader: raw frames + link status (serial, /dev/rfcommN, bt://ADDR, or emulator)."""

    class Params(ReaderConfig):
        """The reader's settings (declared once, in :class:`ReaderConfig`) and the node's."""

        port: Annotated[str, GLOVE_PORT] = Field(
            "emulator", description="serial device, bt://AA:BB:CC:DD:EE:FF[/channel], or 'emulator'"
        )
        rate_hz: float = Field(500.0, gt=0, description="how often the node drains the reader and publishes")
        status_period_s: float = Field(1.0, gt=0, description="link status is published at least this often")
        emulator: EmulatorParams = Field(default_factory=EmulatorParams)

    outputs = {"frames": GloveFrame, "status": Status}

    def setup(self) -> None:
        p = self.params
        self.emulator = None
        port = p.port
        if port == "emulator":
            self.emulator = build_emulator(p.emulator, self.ctx.resolve_path, source=self.emulator_source()).start()
            port = self.emulator.path
        elif (problem := missing_device_message(port)) is not None:
            self.ctx.log.error("%s; retrying in the background", problem)
        cfg = ReaderConfig(**p.model_dump(include=set(ReaderConfig.model_fields) - {"port"}), port=port)
        self.reader = GloveReader(cfg, clock_ns=self.ctx.now_ns).start()
        self._last_state = None
        self._last_status_ns = None
        self.published = 0

    def emulator_source(self):
        """The embedded emulator's record source (None: the one ``emulator`` names); subclasses perform."""
        return None

    def _publish_pending(self) -> None:
        for rec, arrival_ns in self.reader.drain():
            self.ctx.publish(
                "frames",
                GloveFrame(sensors=rec.values, device_time=rec.device_time, status=rec.status, arrival_ns=arrival_ns),
                stamp_ns=arrival_ns,
            )
            self.published += 1

    def tick(self) -> None:
        self._publish_pending()
        state, _ = self.reader.snapshot()
        now = self.ctx.now_ns()
        due = self._last_status_ns is None or now - self._last_status_ns >= self.params.status_period_s * 1e9
        if state != self._last_state or due:
            self.ctx.publish("status", self.status())
            self._last_state, self._last_status_ns = state, now

    def status(self) -> Status:
        state, counters = self.reader.snapshot()
        counters["published"] = float(self.published)
        level = {"streaming": "ok", "connecting": "warn", "stalled": "warn", "stopped": "warn"}.get(state, "error")
        text = f"link {state} on {self.reader.cfg.port}"
        if self.reader.last_error and state != "streaming":
            text += f" (last error: {self.reader.last_error})"
        return Status(state=level, counters=counters, text=text)

    def safe_output(self) -> dict[str, Status]:
        """The final link status and counters."""
        return {"status": self.status()}

    def teardown(self) -> None:
        self.reader.stop()
        self._publish_pending()  # what arrived before the reader stopped is not dropped
        if self.emulator:
            self.emulator.stop()
