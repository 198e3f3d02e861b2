"""Counting ball swaps from ball positions (docs/simulator.md closed loop).

The two health balls are identical, so the counter must not depend on which ball is called 1:
it follows the *undirected* line through both balls.  The doubled angle
``ψ = 2·atan2(p2 − p1)`` is the same for (p1, p2) and (p2, p1); unwrapped over time, ``ψ / 2``
is the pair's rotation angle θ and a **swap is half a revolution of the pair, Δθ = π**
(the balls exchange places by circling around each other).  Works on palm-plane positions from the
simulator (:meth:`handflow.plugins.simulator.scenes.BallsScene.palm_plane_positions`) and on the tracker's
normalised image positions alike (a mirror image only flips the sign of θ).

Documented choice: samples must be dense enough that the pair turns less than π/2 between two
samples (the doubled angle then unwraps correctly); rows with NaN (a ball not seen) are dropped.
"""

from __future__ import annotations

import numpy as np


def _valid_pairs(p1, p2) -> tuple[np.ndarray, np.ndarray]:
    a, b = np.asarray(p1, dtype=float), np.asarray(p2, dtype=float)
    if a.ndim != 2 or a.shape[1] != 2 or a.shape != b.shape:
        raise ValueError(f"p1 and p2 must both be (n, 2) arrays of 2D positions, got {a.shape} and {b.shape}")
    keep = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    return keep, b[keep] - a[keep]


def pair_rotation(p1, p2) -> np.ndarray:
    """Unwrapped rotation θ (rad) of the line through both balls, relative to the first valid sample.

    Returns one value per input row; rows where a ball is NaN get NaN.
    """
    keep, d = _valid_pairs(p1, p2)
    out = np.full(keep.size, np.nan)
    if d.shape[0]:
        psi = np.unwrap(2.0 * np.arctan2(d[:, 1], d[:, 0]))
        out[keep] = (psi - psi[0]) / 2.0
    return out


def swap_progress(p1, p2) -> np.ndarray:
    """Signed number of swaps done so far (θ / π, float) per sample; NaN where a ball is missing."""
    return pair_rotation(p1, p2) / np.pi


def count_swaps(p1, p2, direction: int = 0) -> int:
    """Net completed swaps (whole half revolutions) in ``direction`` (+1 / −1; 0: the net direction).

    Back-and-forth motion counts nothing; a swap undone by turning back is not counted.
    """
    if direction not in (-1, 0, 1):
        raise ValueError(f"direction must be -1, 0 or +1, got {direction}")
    progress = swap_progress(p1, p2)
    progress = progress[np.isfinite(progress)]
    if progress.size == 0:
        return 0
    net = progress[-1]
    sign = direction or (1 if net >= 0 else -1)
    return max(int(np.floor(sign * net + 1e-9)), 0)


def swap_times(times_s, p1, p2, direction: int = 0) -> np.ndarray:
    """Times at which the net swap count first reaches 1, 2, … (in ``direction``; 0: net direction)."""
    t = np.asarray(times_s, dtype=float)
    progress = swap_progress(p1, p2)
    if t.shape != progress.shape:
        raise ValueError(f"times_s has {t.size} samples but the positions have {progress.size}")
    n = count_swaps(p1, p2, direction)
    if n == 0:
        return np.empty(0)
    ok = np.isfinite(progress)
    sign = direction or (1 if progress[ok][-1] >= 0 else -1)
    level = sign * progress[ok]
    return np.array([t[ok][np.argmax(level >= k - 1e-9)] for k in range(1, n + 1)])


def swaps_per_minute(times_s, p1, p2, direction: int = 0) -> float:
    """Net swaps divided by the covered time span in minutes."""
    t = np.asarray(times_s, dtype=float)
    span = float(t[-1] - t[0]) if t.size > 1 else 0.0
    if span <= 0:
        raise ValueError("swaps_per_minute needs at least two samples spanning a positive time")
    return 60.0 * count_swaps(p1, p2, direction) / span
