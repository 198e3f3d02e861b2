"""A counter video: an MJPG ``.avi`` whose frames carry their own index (tests and docs/camera.md).

Each frame has a colour gradient that moves with the frame and its index as 8 black/white squares
(bit 7 first) along the top, large enough to survive JPEG; :func:`frame_counter` reads it back::

    python -m handflow.plugins.camera.synthetic out/counter.avi --frames 40 --fps 20
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

BITS = 8
SQUARE = 16  # pixels per counter square (the frame is at least BITS × SQUARE wide)


def counter_frame(index: int, width: int, height: int) -> np.ndarray:
    """Frame ``index`` as RGB (height × width × 3, uint8)."""
    y, x = np.mgrid[0:height, 0:width]
    rgb = np.stack([(x * 255 // max(width - 1, 1) + 8 * index) % 256, y * 255 // max(height - 1, 1),
                    np.full_like(x, 96)], axis=-1).astype(np.uint8)  # fmt: skip
    for bit in range(BITS):
        on = (index >> (BITS - 1 - bit)) & 1
        rgb[:SQUARE, bit * SQUARE : (bit + 1) * SQUARE] = 255 if on else 0
    return rgb


def frame_counter(rgb: np.ndarray) -> int:
    """The index a :func:`counter_frame` carries (read from the centres of its squares)."""
    c = SQUARE // 2
    bits = [int(rgb[c, bit * SQUARE + c].mean() > 127) for bit in range(BITS)]
    return int("".join(map(str, bits)), 2)


def write_counter_video(
    path: str | Path, frames: int = 40, width: int = 160, height: int = 120, fps: float = 20.0
) -> Path:
    """Write ``frames`` counter frames as MJPG ``.avi`` with OpenCV's ``VideoWriter``; returns the path."""
    if width < BITS * SQUARE or height < SQUARE:
        raise ValueError(f"a counter video is at least {BITS * SQUARE}×{SQUARE} pixels, got {width}×{height}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (width, height))
    if not writer.isOpened():
        raise OSError(f"OpenCV cannot write {path}; use a .avi path in a writable folder")
    try:
        for i in range(frames):
            writer.write(cv2.cvtColor(counter_frame(i, width, height), cv2.COLOR_RGB2BGR))
    finally:
        writer.release()
    return path


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        prog="python -m handflow.plugins.camera.synthetic", description=__doc__.splitlines()[0]
    )
    ap.add_argument("path", help="output .avi")
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--fps", type=float, default=20.0)
    args = ap.parse_args(argv)
    try:
        path = write_counter_video(args.path, args.frames, args.width, args.height, args.fps)
    except (OSError, ValueError) as exc:
        raise SystemExit(f"error: {exc}") from None
    print(f"wrote {path}: {args.frames} frames of {args.width}×{args.height} at {args.fps:g} fps (MJPG)")


if __name__ == "__main__":
    main()
