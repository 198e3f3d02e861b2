"""What every part of the segmenter shares: the rejected label and runs of equal labels
(docs/segmentation.md)."""

from __future__ import annotations

import numpy as np

REJECTED = -1


def runs(labels: np.ndarray) -> list[tuple[int, int, int]]:
    """Maximal runs of one label as ``(label, start, end)`` with ``end`` exclusive."""
    labels = np.asarray(labels)
    if labels.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(labels)) + 1
    starts, ends = np.r_[0, cuts], np.r_[cuts, labels.size]
    return [(int(labels[a]), int(a), int(b)) for a, b in zip(starts, ends)]


def lagged(labels: np.ndarray, lag: int) -> np.ndarray:
    """Each frame's label from the evidence of the window ending ``lag`` frames later
    (docs/segmentation.md, "Labels with a lag"): ``labels`` moved ``lag`` frames earlier.  The
    last ``lag`` frames have no such window; they keep the recording's last label (documented
    choice: the node publishes them only when the stream goes on)."""
    labels = np.asarray(labels)
    if lag < 0:
        raise ValueError(f"lag must be >= 0 frames, got {lag}")
    if lag == 0 or labels.size == 0:
        return labels
    return np.r_[labels[lag:], np.repeat(labels[-1:], min(lag, labels.size))]
