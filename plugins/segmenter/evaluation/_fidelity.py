"""What a fit or a calibration of the evaluation may spend (docs/segmentation.md, "successive
halving"): the full models that label a held-out recording (:data:`FULL`), and the
cheaper ones the successive halving of :mod:`._selection` screens and refines candidates with
(:data:`SCREEN`; the survivors are refined at full fidelity, :data:`REFINE`), each protocol's
halving (:data:`NESTED`, :data:`PREVIEW`; documented choices)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
REFINE = Fidelity("refine")  # the survivors: full models, the whole sweep
SCREEN = Fidelity("screen", max_points=250, steps=60, statistics_frames=500, pseudo_unknowns="drop", reject_stride=3)


@dataclass(frozen=True)
class Halving:
    """A protocol's successive halving: the ``screen`` every candidate gets, the share ``keep`` of
    them (at least one) refined at ``refine``."""

    screen: Fidelity
    refine: Fidelity
    keep: float


NESTED = Halving(SCREEN, REFINE, keep=1 / 3)
# The preview's own (docs/segmentation.md, "The preview protocol"): the nested protocol's screen and
# survivors, refined with a quarter of the class manifolds' statistics frames; its refined fits are
# its reported fits.
PREVIEW = Halving(SCREEN, Fidelity("preview", statistics_frames=1000), keep=NESTED.keep)
