"""``handflow demo-record {cap,balls} --out FILE.mcap``: seeded demonstration recordings (docs/manipulation.md)."""

from __future__ import annotations

import argparse
import sys

from handflow.framework.files.mcap_writer import RecordingError

from .demonstrations import CAP_RADII, record_balls, record_cap


def register_demo_record(parser: argparse.ArgumentParser) -> None:
    """Record scripted cap-turning or ball-swapping demonstrations from the simulator into an MCAP file."""
    parser.add_argument(
        "task",
        choices=["cap", "balls"],
        help="cap: ShadowHand-like hand turning caps; "
        "balls: Gifu-like hand moving two health balls (tracked by camera)",
    )
    parser.add_argument("--out", required=True, help="output .mcap file")
    parser.add_argument("--seed", type=int, default=0, help="seed of all variation (same seed → same file)")
    parser.add_argument(
        "--radii",
        type=float,
        nargs="+",
        default=[r * 100 for r in CAP_RADII],
        metavar="CM",
        help="cap radii in cm (cap only; default 1.5 2.0 2.5 3.0 3.5)",
    )
    parser.add_argument(
        "--sequences", type=int, default=None, help="sequences per radius (cap only; default: 5–9 drawn from the seed)"
    )
    parser.add_argument("--with-targets", action="store_true", help="also record the commanded targets (cap only)")
    parser.add_argument(
        "--cycles", type=int, default=4, help="swap cycles = ball periods, two hand cycles each (balls only)"
    )
    parser.set_defaults(func=run)


def _progress(line: str) -> None:
    print(f"\r{line}\033[K", end="", file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    if not str(args.out).endswith(".mcap"):
        print(f"demo-record: --out must name a .mcap file, got '{args.out}'", file=sys.stderr)
        return 2
    try:
        if args.task == "cap":
            bad = [r for r in args.radii if not 1.0 <= r <= 5.0]
            if bad:
                print(f"demo-record: --radii are in cm and must lie in 1–5 cm, got {bad}", file=sys.stderr)
                return 2
            s = record_cap(
                args.out,
                [r / 100 for r in args.radii],
                args.sequences,
                args.seed,
                include_targets=args.with_targets,
                progress=_progress,
            )
            print(
                f"\nwrote {s.postures} postures in {sum(s.sequences.values())} sequences to {s.path}", file=sys.stderr
            )
        else:
            b = record_balls(args.out, args.cycles, args.seed, progress=_progress)
            print(
                f"\nwrote {b.frames} frames, {b.observations} observations (d = 20), {b.swaps} swaps to {b.path}",
                file=sys.stderr,
            )
    except (ValueError, RecordingError) as exc:
        print(f"\ndemo-record: {exc}", file=sys.stderr)
        return 2
    return 0
