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
