"""Segment rules judged after the CLM: too little progress, poor fit (docs/segmentation.md)."""

from __future__ import annotations

import numpy as np

from ..base import runs
from ._unwrapping import unwrapped_latent


def reject_small_progress(labels: np.ndarray, latent_time: np.ndarray, min_progress: float) -> np.ndarray:
    """Labels (N,) of candidate indices with every segment that moves less than ``min_progress``
    periods forward along its own candidate's latent time set to −1.

    A segment is a maximal run of one label; its progress is the net change of that candidate's
    unwrapped latent path (:func:`unwrapped_latent`, latent period π) from its first to its last
    observation, divided by π.  Documented choice (docs/segmentation.md): a motion is recognised
    only once it has covered a share of its manifold.  A piece of another motion that happens to
    match a short arc of a candidate — a letter written backwards matches short forward arcs of
    other letters — covers little of it, a performed motion covers most of it (or repeats it).
    """
    if min_progress < 0:
        raise ValueError(f"min_progress must be >= 0 periods, got {min_progress}")
    out = np.array(labels, dtype=int, copy=True)
    if min_progress == 0 or out.size == 0:
        return out
    path = unwrapped_latent(latent_time)
    for label, start, stop in runs(out):
        if label >= 0 and (path[stop - 1, label] - path[start, label]) / np.pi < min_progress:
            out[start:stop] = -1
    return out


def reject_poor_fit(
    labels: np.ndarray,
    errors: np.ndarray,
    max_fit_ratio: float | None,
    reversed_errors: np.ndarray | None = None,
) -> np.ndarray:
    """Labels (N,) of candidate indices with every segment whose candidate fits it worse than
    ``max_fit_ratio`` times the best-fitting candidate set to −1 (``None`` = off).

    A segment is a maximal run of one label; a candidate's fit is its mean error over the segment
    (``errors`` (N, M)).  Documented choice (docs/segmentation.md): the CLM weighs fit against
    forward order, so a motion whose own manifold runs backward through it — a letter written
    backwards — goes to another candidate that moves forward but fits it several times worse; a
    recognised motion's candidate is (nearly) the best fit.  ``reversed_errors`` (N, M): the
    errors of the observations with their headings turned round (:mod:`..features`); the best fit
    is then also sought among the candidates traversed backward.
    """
    out = np.array(labels, dtype=int, copy=True)
    if max_fit_ratio is None or out.size == 0:
        return out
    if not max_fit_ratio >= 1:
        raise ValueError(f"max_fit_ratio must be >= 1 (or None = off), got {max_fit_ratio}")
    E = np.asarray(errors, dtype=float)
    R = None if reversed_errors is None else np.asarray(reversed_errors, dtype=float)
    for label, start, stop in runs(out):
        if label >= 0:
            fit = E[start:stop].mean(axis=0)
            best = fit.min() if R is None else min(fit.min(), R[start:stop].mean(axis=0).min())
            if fit[label] > max_fit_ratio * best:
                out[start:stop] = -1
    return out


def reject_segments(
    labels: np.ndarray,
    latent_time: np.ndarray,
    errors: np.ndarray,
    min_progress: float = 0.0,
    max_fit_ratio: float | None = None,
    open_ends: tuple[bool, bool] = (False, False),
    reversed_errors: np.ndarray | None = None,
) -> np.ndarray:
    """The segment rules applied after the CLM: :func:`reject_poor_fit` (with ``reversed_errors``),
    then :func:`reject_small_progress` (a segment the first rejects takes no part in the second).

    ``open_ends`` (start, end): whether the sequence is cut out of a longer stream there; a segment
    touching an open end is left as it is, since only part of it is in view (documented choice,
    docs/segmentation.md).
    """
    judged = reject_small_progress(
        reject_poor_fit(labels, errors, max_fit_ratio, reversed_errors), latent_time, min_progress
    )
    if not any(open_ends):
        return judged
    out = np.array(labels, dtype=int, copy=True)
    for _, start, stop in runs(out):
        if not ((open_ends[0] and start == 0) or (open_ends[1] and stop == out.size)):
            out[start:stop] = judged[start:stop]
    return out
