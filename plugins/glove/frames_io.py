"""Raw glove frames from and to files: ``.npy``, ``.csv`` (n × 22 integers) or MCAP recordings.

MCAP files are read and written with :mod:`handflow.framework.files.mcap_writer` (GloveFrame messages, JSON), so a
recording made by the runtime, by ``handflow calibrate`` or by :func:`save_frames` all work.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from handflow.framework.files.mcap_reader import read_messages
from handflow.framework.files.mcap_writer import McapWriter, RecordingError
from handflow.framework.messages import GloveFrame
from handflow.plugins.hands.sensors import N_SENSORS

DEFAULT_TOPIC = "handflow/glove/glove/frames"


def load_frames(path: str | Path, topic: str | None = None) -> np.ndarray:
    """Raw frames (n, 22) int64 from a ``.npy``, ``.csv`` or ``.mcap`` file (MCAP: every GloveFrame,
    or only those on ``topic``)."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"glove frame file '{p}' not found")
    suffix = p.suffix.lower()
    if suffix == ".mcap":
        try:
            rows = [
                m.sensors for t, m, _ in read_messages(p) if isinstance(m, GloveFrame) and (topic is None or t == topic)
            ]
        except RecordingError as exc:
            raise ValueError(f"cannot read glove frames from '{p}': {exc}") from None
        if not rows:
            raise ValueError(
                f"'{p}' holds no GloveFrame messages{f' on {topic}' if topic else ''}; "
                "record the glove's 'frames' output"
            )
        frames = np.stack(rows)
    elif suffix == ".npy":
        frames = np.load(p)
    elif suffix == ".csv":
        frames = np.loadtxt(p, delimiter=",", ndmin=2)
    else:
        raise ValueError(f"unsupported glove frame file '{p}': use .npy, .csv or .mcap")
    frames = np.asarray(frames)
    if frames.ndim != 2 or frames.shape[1] != N_SENSORS or len(frames) == 0:
        raise ValueError(f"'{p}' must hold an (n, {N_SENSORS}) array of raw sensor values, got shape {frames.shape}")
    if frames.min() < 0 or frames.max() > 255:
        raise ValueError(f"'{p}' holds values outside 0..255; these are not raw CyberGlove readings")
    return frames.astype(np.int64)


def save_frames(path: str | Path, frames: np.ndarray, rate_hz: float = 100.0, topic: str = DEFAULT_TOPIC) -> Path:
    """Write raw frames as ``.npy``/``.csv``, or as an MCAP recording of GloveFrames at ``rate_hz``."""
    p = Path(path)
    frames = np.asarray(frames, dtype=np.int64)
    if p.suffix.lower() == ".mcap":
        with McapWriter(p, flush_interval_s=None) as w:
            for k, row in enumerate(frames):
                t = int(k * 1e9 / rate_hz)
                w.write(topic, GloveFrame(sensors=row, arrival_ns=t), t, t)
    elif p.suffix.lower() == ".csv":
        np.savetxt(p, frames, fmt="%d", delimiter=",")
    else:
        np.save(p, frames)
    return p
