"""Advancing the latent time of a manipulation manifold (docs/manipulation.md).

A periodic time axis (learned manifolds, period π) wraps smoothly; a constructed time axis has
two ends, so the time jumps back to the start when it passes the end (the visible jerk of the
thesis, 5.2.1).  Every pass over the end counts one motion cycle.
"""

from __future__ import annotations

import numpy as np


class LatentClock:
    """Time coordinate on ``[lo, hi]`` advanced by ``delta`` per step; ``cycles`` counts the wraps."""

    def __init__(self, lo: float, hi: float, periodic: bool, start: float | None = None) -> None:
        if not hi > lo:
            raise ValueError(f"latent time range [{lo}, {hi}] is empty")
        self.lo, self.hi, self.periodic = float(lo), float(hi), bool(periodic)
        self.value = self.lo if start is None else self._into_range(float(start))
        self.cycles = 0

    def _into_range(self, t: float) -> float:
        if self.periodic:
            return self.lo + float(np.mod(t - self.lo, self.hi - self.lo))
        return float(np.clip(t, self.lo, self.hi))

    def advance(self, delta: float) -> float:
        """Move by ``delta`` (may be negative on a periodic axis); returns the new time."""
        t = self.value + float(delta)
        if self.periodic:
            span = self.hi - self.lo
            self.cycles += int(np.floor((t - self.lo) / span))
            t = self.lo + float(np.mod(t - self.lo, span))
        elif t > self.hi:
            self.cycles += 1
            t = self.lo
        elif t < self.lo:
            t = self.lo
        self.value = t
        return t

    def ahead(self, deltas) -> np.ndarray:
        """Times ``value + deltas`` without moving the clock (wrapped or reset like ``advance``)."""
        t = self.value + np.asarray(deltas, dtype=float)
        if self.periodic:
            return self.lo + np.mod(t - self.lo, self.hi - self.lo)
        return np.where(t > self.hi, self.lo + (t - self.hi), np.maximum(t, self.lo))
