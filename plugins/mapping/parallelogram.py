"""Thumb roll/abduction from the cross-coupled sensors 1 and 4 (docs/glove.md, thesis 3.4.1–3.4.2).

In the plane ``x = s1`` (roll), ``y = s4`` (abduction) the data fill a parallelogram bounded by
``y = m13·x + b1`` / ``y = m13·x + b3`` (left/right) and ``y = m24·x + b4`` / ``y = m24·x + b2``
(bottom/top).  A reading's askew coordinates are the intercepts of the lines of slope m13 and m24
through it, ``c13 = y − m13·x`` and ``c24 = y − m24·x``; relative positions
``u = (c13 − b1)/(b3 − b1)`` (roll) and ``v = (c24 − b4)/(b2 − b4)`` (abduction), clipped to [0, 1].

Calibration "method 2" (the thesis' standard): the slopes are fitted once per glove
(:func:`fit_slopes`, minimal-area robust bounding parallelogram) and stored in the glove profile;
each session only shifts the four lines to the session's robust extremes (:func:`fit_intercepts`).
Robust extreme (documented choice, :func:`robust_extremes`): the ``support``-th smallest/largest
value, so a few isolated outliers (the other hand pressing a sensor) are rejected and reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def robust_extremes(values, support: int = 5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per column of ``values`` (n, k): low, high = the ``support``-th smallest/largest value, and
    the number of rejected samples (outside [low, high]) per column."""
    v = np.asarray(values, dtype=float)
    v2 = v.reshape(len(v), -1)
    n = len(v2)
    if n == 0:
        raise ValueError("no samples to calibrate from")
    k = min(max(1, support), n) - 1
    part = np.partition(v2, (k, n - 1 - k), axis=0)
    lo, hi = part[k], part[n - 1 - k]
    rejected = ((v2 < lo) | (v2 > hi)).sum(axis=0)
    shape = v.shape[1:]
    return lo.reshape(shape), hi.reshape(shape), rejected.reshape(shape)


@dataclass
class Parallelogram:
    """Slopes (per glove) and intercepts b1…b4 (per session) of the thumb parallelogram."""

    m13: float
    m24: float
    b1: float
    b2: float
    b3: float
    b4: float

    def relative(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Relative roll ``u`` and abduction ``v`` in [0, 1] of readings (x = s1, y = s4)."""
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        u = (y - self.m13 * x - self.b1) / (self.b3 - self.b1)
        v = (y - self.m24 * x - self.b4) / (self.b2 - self.b4)
        return np.clip(u, 0.0, 1.0), np.clip(v, 0.0, 1.0)

    def reading(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        """Inverse of :meth:`relative`: the reading (x, y) at relative positions (u, v)."""
        c13 = self.b1 + np.asarray(u, dtype=float) * (self.b3 - self.b1)
        c24 = self.b4 + np.asarray(v, dtype=float) * (self.b2 - self.b4)
        x = (c24 - c13) / (self.m13 - self.m24)
        return x, self.m13 * x + c13


def fit_intercepts(x, y, m13: float, m24: float, support: int = 5) -> tuple[Parallelogram, int]:
    """Session calibration: shift the four lines to bound the robust extremes; returns the
    parallelogram and the number of rejected samples (outside it)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    c = np.stack([y - m13 * x, y - m24 * x], axis=1)
    lo, hi, _ = robust_extremes(c, support)
    if np.any(hi - lo <= 0):
        raise ValueError("thumb calibration data do not span the parallelogram (no thumb motion recorded?)")
    rejected = int(np.any((c < lo) | (c > hi), axis=1).sum())
    return Parallelogram(m13, m24, b1=lo[0], b2=hi[1], b3=hi[0], b4=lo[1]), rejected


def fit_slopes(x, y, support: int = 5, step_deg: float = 0.5, min_angle_deg: float = 20.0) -> tuple[float, float]:
    """Per-glove slopes (m13, m24): the bounding parallelogram of minimal area (robust widths),
    grid search over side directions; m13 is the steeper side (left/right), m24 the flatter."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    angles = np.deg2rad(np.arange(-89.5, 90.0, step_deg))  # direction of a side
    # width across lines of direction θ: projection on the normal (−sin θ, cos θ)
    proj = -np.outer(x, np.sin(angles)) + np.outer(y, np.cos(angles))
    lo, hi, _ = robust_extremes(proj, support)
    width = hi - lo
    sin_between = np.abs(np.sin(angles[:, None] - angles[None, :]))
    area = width[:, None] * width[None, :] / np.maximum(sin_between, 1e-12)
    area[sin_between < np.sin(np.deg2rad(min_angle_deg))] = np.inf
    i, j = np.unravel_index(np.argmin(area), area.shape)
    m = np.tan(angles[[i, j]])
    steep, flat = (m[0], m[1]) if abs(m[0]) >= abs(m[1]) else (m[1], m[0])
    return float(steep), float(flat)
