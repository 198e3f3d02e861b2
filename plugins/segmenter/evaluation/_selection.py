"""Successive halving over a method's candidates on the inner folds (docs/segmentation.md,
"How the parameters are chosen").

A candidate is one normalisation × derived features × grid point of a method.  Every candidate
is first *screened*: calibrated on the inner folds with cheap models (:data:`SCREEN`: UKR
manifolds on fewer points and steps, pseudo-unknowns by dropped columns, every third value of
the rejection sweep).  The best third (:func:`survivors`) is then *refined* with the same
models, refitted pseudo-unknowns and the whole sweep (:data:`REFINE`); the rule of
:func:`first_of_best` picks among those.  Only the chosen candidate is fitted at full fidelity
(:data:`FULL`), on all training recordings, to label the held-out one.  Documented choices:
the fidelities below, ``KEEP`` and ``TIE_MARGIN``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

KEEP = 1 / 3  # share of the screened candidates that are refined (at least one)
TIE_MARGIN = 0.01  # objectives this close to the best are a tie: the first candidate in order wins


@dataclass(frozen=True)
class Fidelity:
    """What a fit or a calibration spends.  ``max_points``, ``steps``, ``statistics_frames``:
    the UKR class models' training points per class, RPROP steps and frames per class behind
    their error statistics (None: the full models' own); ``pseudo_unknowns``: ``"drop"`` drops a
    class's decision column instead of refitting without it (None: the evaluation's setting);
    ``reject_stride``: every k-th value of the rejection sweep, its last value always kept."""

    name: str
    max_points: int | None = None
    steps: int | None = None
    statistics_frames: int | None = None
    pseudo_unknowns: str | None = None
    reject_stride: int = 1

    @property
    def models(self) -> tuple:
        """What changes a fitted model (fits of equal ``models`` are shared)."""
        return (self.max_points, self.steps, self.statistics_frames)

    def sweep(self, values: np.ndarray) -> np.ndarray:
        """The rejection values this fidelity tries, from the method's sweep ``values``."""
        keep = np.unique(np.r_[np.arange(0, len(values), max(1, self.reject_stride)), len(values) - 1])
        return np.asarray(values)[keep]


FULL = Fidelity("full")
REFINE = Fidelity("refine", max_points=250, steps=60, statistics_frames=500)
SCREEN = replace(REFINE, name="screen", pseudo_unknowns="drop", reject_stride=3)


def survivors(objectives: list[float]) -> list[int]:
    """Indices of the screened candidates that are refined: the best ``KEEP`` share, at least
    one, in candidate order (ties keep the earlier candidate)."""
    n_keep = max(1, math.ceil(len(objectives) * KEEP))
    ranked = sorted(range(len(objectives)), key=lambda i: -objectives[i])  # stable
    return sorted(ranked[:n_keep])


def first_of_best(objectives: list[float]) -> int:
    """The chosen candidate: the first whose objective is within ``TIE_MARGIN`` of the best
    (the noise of an objective pooled over a few recordings; candidate order puts the simpler
    views first, so a tie does not flip a choice between files or machines)."""
    top = max(objectives)
    return next(i for i, o in enumerate(objectives) if o >= top - TIE_MARGIN)
