"""Period detection and cycle splitting of multi-cycle recordings (docs/segmentation.md, "Class models").

A class model has one periodic latent time: one period = one repetition of the motion.  Real
recordings of walking, waving or exercise hold many repetitions at varying speed and amplitude,
so training segments are cut into single cycles first:

1. :func:`estimate_period` — the mean period: the first peak of the channel-summed
   autocorrelation of the z-scored, mean-removed segment between ``min_period`` and half the
   segment length; a peak below ``min_correlation`` means "not periodic".
2. :func:`cycle_boundaries` — one boundary per repetition: the peaks of the segment's first
   principal component, at least ``spacing · period`` apart (speed may vary by that factor),
   each required to stand out by ``prominence`` standard deviations.  Found locally, the
   boundaries follow a varying speed; consecutive boundaries enclose one cycle.
3. :func:`split_cycles` — the cycles between consecutive boundaries; the partial cycles before
   the first and after the last boundary are dropped.  A segment that is not periodic, or holds
   fewer than ``min_cycles`` full cycles, is returned whole (one open stroke, e.g. a letter).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import find_peaks


def _standardised(Y: np.ndarray) -> np.ndarray:
    Y = np.asarray(Y, dtype=float)
    if Y.ndim == 1:
        Y = Y[:, None]
    if Y.ndim != 2 or not np.isfinite(Y).all():
        raise ValueError("a segment must be a finite (T, d) array")
    Z = Y - Y.mean(axis=0)
    std = Z.std(axis=0)
    return Z[:, std > 1e-12] / std[std > 1e-12]


def autocorrelation(Y: np.ndarray) -> np.ndarray:
    """Channel-summed autocorrelation of the standardised segment, normalised to 1 at lag 0
    (unbiased: each lag divided by its number of overlapping samples)."""
    Z = _standardised(Y)
    n = Z.shape[0]
    if Z.shape[1] == 0 or n < 4:
        return np.ones(1)
    f = np.fft.rfft(Z, n=2 * n, axis=0)
    ac = np.fft.irfft((f * np.conj(f)).sum(axis=1), n=2 * n)[:n]
    ac = ac / np.arange(n, 0, -1)
    return ac / ac[0]


def estimate_period(Y: np.ndarray, min_period: int = 4, min_correlation: float = 0.2) -> int | None:
    """Mean period in samples, or None when the segment shows no repetition."""
    ac = autocorrelation(Y)
    hi = len(ac) // 2
    if hi <= min_period:
        return None
    peaks, _ = find_peaks(ac[: hi + 1])
    peaks = peaks[(peaks >= min_period) & (ac[peaks] >= min_correlation)]
    if peaks.size == 0:
        return None
    # the first peak that is at least half as high as the best one: not a harmonic of the true period
    best = ac[peaks].max()
    return int(peaks[np.argmax(ac[peaks] >= 0.5 * best)])


def cycle_boundaries(Y: np.ndarray, period: int, spacing: float = 0.6, prominence: float = 0.5) -> np.ndarray:
    """Sample indices that start a new repetition (peaks of the first principal component)."""
    Z = _standardised(Y)
    if Z.shape[1] == 0:
        return np.zeros(0, dtype=int)
    _, _, vt = np.linalg.svd(Z, full_matrices=False)
    pc = Z @ vt[0]
    pc = pc / (pc.std() or 1.0)
    peaks, _ = find_peaks(pc, distance=max(1, int(spacing * period)), prominence=prominence)
    return peaks


def split_cycles(
    Y: np.ndarray,
    min_period: int = 4,
    min_cycles: int = 2,
    min_correlation: float = 0.2,
    spacing: float = 0.6,
    prominence: float = 0.5,
) -> list[np.ndarray]:
    """Single cycles of a (T, d) segment, or ``[Y]`` when it is not periodic (see module doc)."""
    Y = np.asarray(Y, dtype=float)
    period = estimate_period(Y, min_period, min_correlation)
    if period is None:
        return [Y]
    b = cycle_boundaries(Y, period, spacing, prominence)
    cycles = [Y[lo:hi] for lo, hi in zip(b[:-1], b[1:]) if hi - lo >= min_period]
    return cycles if len(cycles) >= min_cycles else [Y]
