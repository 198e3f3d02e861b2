"""Derived features of continuous recordings, chosen on validation like a method's parameters
(docs/segmentation.md, "Derived features").

``"velocities"`` appends to every frame the step from the frame before, ``x_t − x_{t−1}`` of
every channel (the first frame of a recording gets step 0).  The step is taken per frame, not per
second: recordings of one dataset share a nominal rate, and the scaling that follows
(z-scored or running, :mod:`.running_scaling`) gives the new channels unit spread anyway.  The
steps are causal, so a stream can append them sample by sample as a recording does at once.
"""

from __future__ import annotations

import numpy as np

DERIVED = ("none", "velocities")


def derive(X: np.ndarray, kind: str) -> np.ndarray:
    """Frames (T, d) with the derived features ``kind`` appended: (T, d) for ``"none"``, (T, 2d)
    for ``"velocities"``."""
    if kind not in DERIVED:
        raise ValueError(f"derived features must be one of {DERIVED}, got {kind!r}")
    X = np.asarray(X, dtype=float)
    if kind == "none":
        return X
    return np.hstack([X, np.diff(X, axis=0, prepend=X[:1])])
