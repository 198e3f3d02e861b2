"""Shared opening of the segmentation benchmarks: a continuous recording set named on the command line."""

from __future__ import annotations

import sys
from pathlib import Path

from handflow.plugins.segmenter.datasets import RecordingSet, load_recordings


def open_recordings(path: Path) -> RecordingSet | None:
    """The recording set at ``path``, or None after saying what to pass (the caller exits 2)."""
    if not path.exists():
        print(f"{path} not found; pass a continuous recording set (docs/segmentation.md)", file=sys.stderr)
        return None
    return load_recordings(path)
