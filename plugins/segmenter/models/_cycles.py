"""Period detection and cycle splitting of repeated motion (docs/segmentation.md).

A class model with a periodic latent time covers *one* cycle of the motion; real recordings of
walking, waving or exercise hold many repetitions at varying speed.  :func:`split_cycles` cuts a
segment into its cycles so that each cycle becomes one training sequence:

1. :func:`detect_period` — the first peak of the channel-averaged autocorrelation (mean removed)
   after ``min_period`` frames that reaches ``min_correlation``; no such peak = not periodic.
2. Cuts at the minima of the motion's projection on a phase direction (by default the segment's
   first principal component; pass a class-wide direction so that cycles of different segments
   start at the same phase): the first cut is the minimum within the first period, every next one
   the minimum within ``[0.6 P, 1.4 P]`` after the previous cut, so the cycle length follows the
   speed of each repetition.

The pieces are the whole cycles between the first and the last cut (the partial cycles at both
ends are left out): k repetitions starting mid-cycle give k − 1 cycles.  A segment shorter than
two periods, or without a period, stays one sequence.
"""

from __future__ import annotations

import numpy as np

MIN_CORRELATION = 0.3  # documented choice: a weaker autocorrelation peak is not a period
SPAN = (0.6, 1.4)  # a cycle may last 0.6–1.4 detected periods


def detect_period(Y: np.ndarray, min_period: int = 8, min_correlation: float = MIN_CORRELATION) -> int | None:
    """Period in frames of a (T, d) segment, or ``None`` when it does not repeat."""
    Y = np.asarray(Y, dtype=float)
    T = len(Y)
    if T < 2 * min_period + 2:
        return None
    Z = Y - Y.mean(axis=0)
    energy = np.sum(Z * Z, axis=0)
    Z = Z[:, energy > 1e-12 * max(energy.max(), 1e-300)]
    if Z.shape[1] == 0:
        return None
    n = 1 << int(np.ceil(np.log2(2 * T)))
    F = np.fft.rfft(Z, n=n, axis=0)
    ac = np.fft.irfft(F * np.conj(F), n=n, axis=0)[:T]
    ac = (ac / ac[0]).mean(axis=1) * T / (T - np.arange(T))  # unbiased, averaged over channels
    lags = np.arange(min_period, T // 2)
    if lags.size < 3:
        return None
    a = ac[lags]
    peaks = np.flatnonzero((a[1:-1] >= a[:-2]) & (a[1:-1] >= a[2:]) & (a[1:-1] >= min_correlation)) + 1
    return int(lags[peaks[0]]) if peaks.size else None


def phase_direction(Y: np.ndarray) -> np.ndarray:
    """Unit first principal direction of (T, d) data, signed so that its largest entry is positive."""
    Z = np.asarray(Y, dtype=float) - np.mean(Y, axis=0)
    _, _, vt = np.linalg.svd(Z, full_matrices=False)
    v = vt[0]
    return v if v[np.argmax(np.abs(v))] >= 0 else -v


def split_cycles(Y: np.ndarray, direction: np.ndarray | None = None, min_period: int = 8) -> list[np.ndarray]:
    """The cycles of a (T, d) segment (each at least ``SPAN[0]`` periods long), or ``[Y]``."""
    Y = np.asarray(Y, dtype=float)
    P = detect_period(Y, min_period)
    if P is None or len(Y) < 2 * P:
        return [Y]
    u = (Y - Y.mean(axis=0)) @ (phase_direction(Y) if direction is None else direction)
    cuts = [int(np.argmin(u[:P]))]
    while True:
        lo, hi = cuts[-1] + int(SPAN[0] * P), min(cuts[-1] + int(np.ceil(SPAN[1] * P)), len(Y) - 1)
        if lo >= hi:
            break
        cut = lo + int(np.argmin(u[lo : hi + 1]))
        if cut == len(Y) - 1:  # the minimum at the very end: the recording stopped mid-cycle
            break
        cuts.append(cut)
    if len(cuts) < 2:
        return [Y]
    return [Y[a:b] for a, b in zip(cuts[:-1], cuts[1:])]
