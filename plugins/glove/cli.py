"""Commands ``handflow glove-emulator`` and ``handflow calibrate``."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from handflow.plugins.mapping.calibration import (
    DEFAULT_PROFILE,
    CalibrationFileError,
    calibrate_session,
    load_profile,
    save,
)

from .frames_io import load_frames, save_frames
from .node import EmulatorParams, FaultParams, build_emulator, unusable_device_message
from .reader import GloveReader, ReaderConfig

CALIBRATION_STEPS = (
    "Flat hand, fingers together and straight (zero spread), wrist straight",
    "Make a tight fist, thumb over the fingers",
    "Spread all fingers as wide as you can",
    "Bend only the finger tips (DIP/PIP) with straight knuckles, then hyper-extend the fingers",
    "Thumb: sweep it through its whole range — touch each finger tip, then out to the side",
    "Cup the palm (bring thumb and little finger together)",
    "Wrist: flex, extend, bend left and right",
)
"""Guided extremes of a calibration session (docs/glove.md)."""


def _fault(text: str) -> FaultParams:
    """``KIND@RECORD[:SIZE[:DURATION_S]]``, e.g. ``garbage@100:16`` or ``disconnect@300:0:1.5``."""
    try:
        kind, _, rest = text.partition("@")
        parts = rest.split(":")
        kw = {"kind": kind, "at_record": int(parts[0])}
        if len(parts) > 1 and parts[1]:
            kw["size"] = int(parts[1])
        if len(parts) > 2:
            kw["duration_s"] = float(parts[2])
        return FaultParams(**kw)
    except (ValueError, TypeError) as exc:
        raise argparse.ArgumentTypeError(
            f"bad fault '{text}': use KIND@RECORD[:SIZE[:DURATION_S]] with KIND one of garbage, drop_bytes, "
            f"truncate, zero_value, disconnect, stall ({exc})"
        ) from None


# ------------------------------------------------------------------------------------------------
# glove-emulator
# ------------------------------------------------------------------------------------------------
def register_emulator(parser: argparse.ArgumentParser) -> None:
    """Emulate a CyberGlove II on a pseudo-terminal (prints the device path; Ctrl-C to stop)."""
    parser.add_argument("--frames", help="raw frames to loop (.npy/.csv/.mcap); default: synthetic hand motion")
    parser.add_argument("--motion-period", type=float, default=4.0, help="grasp cycle of the synthetic motion (s)")
    parser.add_argument("--noise", type=float, default=0.5, help="sensor noise of the synthetic motion (raw units)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--fault",
        type=_fault,
        action="append",
        default=[],
        metavar="KIND@RECORD[:SIZE[:DURATION_S]]",
        help="inject a fault at a streamed record number (repeatable)",
    )
    parser.add_argument(
        "--rfcomm", action="store_true", help="Bluetooth-like delivery: bursts of 1-5 records, up to 30 ms jitter"
    )
    parser.add_argument("--duration", type=float, help="stop after this many seconds (default: until Ctrl-C)")
    parser.set_defaults(func=run_emulator)


def run_emulator(args: argparse.Namespace) -> int:
    opts = EmulatorParams(
        frames=args.frames,
        motion_period_s=args.motion_period,
        noise=args.noise,
        seed=args.seed,
        faults=args.fault,
        **({"burst": 5, "jitter_s": 0.03} if args.rfcomm else {}),
    )
    try:
        emu = build_emulator(opts)
    except (OSError, ValueError) as exc:
        print(f"glove-emulator: {exc}", file=sys.stderr)
        return 2
    emu.start()
    print(emu.path, flush=True)
    print(
        f"CyberGlove II emulator on {emu.path} (pty {Path(emu.path).resolve()}); use it as the glove port. "
        "Ctrl-C to stop.",
        file=sys.stderr,
    )
    try:
        end = time.monotonic() + args.duration if args.duration else None
        while end is None or time.monotonic() < end:
            time.sleep(0.1 if end is None else max(0.0, min(0.1, end - time.monotonic())))
    except KeyboardInterrupt:
        pass
    finally:
        emu.stop()
    print(f"emulator stopped: {emu.counters}", file=sys.stderr)
    return 0


# ------------------------------------------------------------------------------------------------
# calibrate
# ------------------------------------------------------------------------------------------------
def register_calibrate(parser: argparse.ArgumentParser) -> None:
    """Record a guided calibration session (live/emulated glove or a recording) and write the calibration file."""
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--port", help="glove device (serial, /dev/rfcommN, bt://ADDR) or 'emulator'")
    src.add_argument("--recording", help="raw frames of a recorded session (.mcap/.npy/.csv)")
    parser.add_argument("--output", "-o", required=True, help="session calibration file to write (.yaml or .json)")
    parser.add_argument("--profile", default=str(DEFAULT_PROFILE), help="glove profile (per-glove parameters)")
    parser.add_argument("--topic", help="MCAP topic of the glove frames (default: every GloveFrame)")
    parser.add_argument("--step-seconds", type=float, default=5.0, help="recording time per guided step")
    parser.add_argument("--glove-rate", type=float, default=100.0, help="glove sample rate (Hz)")
    parser.add_argument(
        "--support",
        type=int,
        default=5,
        help="robust extreme: the N-th most extreme reading (rejects up to N-1 outliers)",
    )
    parser.add_argument("--save-session", help="also save the raw session frames (.mcap/.npy/.csv)")
    parser.set_defaults(func=run_calibrate)


def _record_live(args: argparse.Namespace) -> np.ndarray:
    emulator = None
    port = args.port
    if port == "emulator":
        emulator = build_emulator(EmulatorParams(motion_period_s=2.0)).start()
        port = emulator.path
    reader = GloveReader(ReaderConfig(port=port, glove_rate_hz=args.glove_rate)).start()
    rows: list[np.ndarray] = []
    try:
        for i, step in enumerate(CALIBRATION_STEPS, 1):
            print(f"\nStep {i}/{len(CALIBRATION_STEPS)}: {step}", file=sys.stderr, flush=True)
            end = time.monotonic() + args.step_seconds
            while (left := end - time.monotonic()) > 0:
                time.sleep(min(0.1, left))
                rows.extend(rec.values for rec, _ in reader.drain())
                state, counters = reader.snapshot()
                print(
                    f"\r  {left:4.1f} s left · {len(rows)} frames · link {state} · corrupt {counters['corrupt']:.0f}   ",
                    end="",
                    file=sys.stderr,
                    flush=True,
                )
        print(file=sys.stderr)
    finally:
        reader.stop()
        rows.extend(rec.values for rec, _ in reader.drain())
        if emulator:
            emulator.stop()
    if not rows:
        raise RuntimeError(
            f"no frames from the glove on {port} ({reader.last_error or 'no data'}); "
            "check the port and that the glove is switched on"
        )
    return np.stack(rows)


def run_calibrate(args: argparse.Namespace) -> int:
    try:
        profile = load_profile(args.profile)
        frames = load_frames(args.recording, args.topic) if args.recording else None
    except (CalibrationFileError, FileNotFoundError, ValueError) as exc:
        print(f"calibrate: {exc}", file=sys.stderr)
        return 2
    if frames is None and (problem := unusable_device_message(args.port)) is not None:
        print(f"calibrate: {problem}", file=sys.stderr)  # before the guided session, not after it
        return 2
    if frames is None:
        try:
            frames = _record_live(args)
        except (RuntimeError, OSError) as exc:
            print(f"calibrate: {exc}", file=sys.stderr)
            return 1
    if args.save_session:
        save_frames(args.save_session, frames, args.glove_rate)
    try:
        calib = calibrate_session(frames, profile, args.support)
    except ValueError as exc:
        print(f"calibrate: {exc}", file=sys.stderr)
        return 2
    save(calib, args.output)
    print(f"wrote {args.output}: {calib.n_samples} frames, profile '{profile.name}'")
    rejected = {k: v for k, v in calib.rejected.items() if v}
    if rejected:
        print(
            f"samples set aside beyond the robust extremes (≤ {args.support - 1} per side by design; "
            "more on the thumb, whose two sensors are combined): " + ", ".join(f"{k} {v}" for k, v in rejected.items())
        )
    return 0
