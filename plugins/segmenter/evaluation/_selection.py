"""Successive halving over a method's candidates on the inner folds (docs/segmentation.md,
"successive halving").

A candidate is one normalisation × derived features × grid point of a method; the CLM over a
scorer's scores (``clm_minirocket``, ``clm_dtw``) has one, the candidate its scorer's rule chose,
and calibrates only its null class's score there (documented choice: it segments the scores the
scorer's own selection chose, at a fifth of the CLM runs).  Every candidate
is first *screened*: calibrated on the inner folds with cheap models (:data:`SCREEN`: UKR
manifolds on fewer points and steps, pseudo-unknowns by dropped columns, every third value of
the rejection sweep).  The best third (:func:`survivors`, ranked as the calibration rule ranks:
by the objective, or by the known accuracy where rejection falls back) is then *refined* with full
models, refitted pseudo-unknowns and the whole sweep (:data:`REFINE`); the calibration rule
picks among those (:meth:`._calibration.InnerFoldCalibration._rule`: the best objective, exact
ties to the first).  Only the chosen candidate is fitted at full fidelity (:data:`FULL`), on all
training recordings, to label the held-out one.  Documented choices: the fidelities of
:mod:`._fidelity` (each protocol's :class:`~._fidelity.Halving`).

:func:`first_of_best` is the labelled-trajectory protocol's rule for choices made on a single
small validation split (``TIE_MARGIN``).  The continuous protocol pools its objective over the
inner folds and takes no margin: on BasicMotions a margin of 0.01 picked the plain channels over
velocities in folds where the velocities were 0.005 ahead, and cost the HMM baseline 0.11 of
open-set accuracy (docs/benchmarks.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

from ._fidelity import NESTED
from ._methods import REGISTRY

if TYPE_CHECKING:
    from ._calibration import Choice, Split

TIE_MARGIN = 0.01  # objectives this close to the best are a tie: the first candidate in order wins


def survivors(objectives: list[float], keep: float = NESTED.keep) -> list[int]:
    """Indices of the screened candidates that are refined: the best ``keep`` share, at least
    one, in candidate order (ties keep the earlier candidate)."""
    n_keep = max(1, math.ceil(len(objectives) * keep))
    ranked = sorted(range(len(objectives)), key=lambda i: -objectives[i])  # stable
    return sorted(ranked[:n_keep])


def first_of_best(objectives: list[float]) -> int:
    """The chosen candidate: the first whose objective is within ``TIE_MARGIN`` of the best
    (the noise of an objective pooled over a few recordings; candidate order puts the simpler
    views first, so a tie does not flip a choice between files or machines)."""
    top = max(objectives)
    return next(i for i, o in enumerate(objectives) if o >= top - TIE_MARGIN)


class HalvingSelection:
    """The selection part of :class:`._recordings.RecordingsEvaluator`: a method's choice in a fold
    by successive halving over its candidates, calibrated on the inner folds
    (:class:`._calibration.InnerFoldCalibration`)."""

    def _select(self, name: str, views: dict[tuple[str, str], list[Split]]) -> Choice:
        """Normalisation, derived features, hyper-parameters and rejection value of one method, chosen
        on the splits of ``views`` ((normalisation, derived) → its splits: the inner folds of the
        training recordings, :func:`._calibration.inner_folds`; the preview: the outer folds)."""
        method = REGISTRY[name]
        gate = (
            None
            if method.rejects_with is None
            else max(c.objective for c, *_ in self._choices(method.rejects_with, views))
        )
        return self._rule(name, self._choices(method, views), gate)

    def _choices(self, method, views: dict[tuple[str, str], list[Split]]) -> list[tuple[Choice, float, Callable]]:
        """The parameter sets of ``method`` (normalisation and derived features included) that
        survive the screen, calibrated on the splits of ``views`` (:mod:`._selection`); once per
        fold, whether for the method itself or as the scorer another method rejects with."""
        if method.name not in self._fold_choices:
            candidates = [
                (splits, {**params, "derived": derived, "normalise": normalise})
                for (normalise, derived), splits in views.items()
                for params in method.grid(self.quick)
            ]
            if method.rejects_with is not None:  # the CLM over a scorer: the scorer's chosen candidate
                scorer = method.rejects_with
                chosen = self._rule(scorer.name, self._choices(scorer, views)).params
                candidates = [(splits, params) for splits, params in candidates if params == chosen]
            if len(candidates) > 1:
                halving = self.halving
                self._warm(method, candidates, halving.screen)
                screened = [self._calibrated(method, splits, params, halving.screen) for splits, params in candidates]
                ranking = self._ranking(screened)
                kept = survivors(ranking, halving.keep)
                self.screened(method.name, [params for _, params in candidates], screened, ranking, kept)
                candidates = [candidates[i] for i in kept]
            self._warm(method, candidates, self.halving.refine)
            self._fold_choices[method.name] = [
                self._calibrated(method, splits, params, self.halving.refine) for splits, params in candidates
            ]
        return self._fold_choices[method.name]

    def screened(self, name: str, candidates: list[dict], screened: list, ranking: list[float], kept: list[int]):
        """The screen's provisional ranking of a method's ``candidates`` (their screened
        calibrations and what ranks them, :meth:`._calibration.InnerFoldCalibration._ranking`;
        ``kept``: the refined ones): on stderr in the preview, with ``--verbose`` in the nested
        protocol."""
        say = self.progress if self.preview else self.detail
        by = "pooled objective" if ranking == [c.objective for c, *_ in screened] else "keep-all known accuracy"
        say(f"  {name}: screen of {len(candidates)} candidates, provisional ranking by {by} (cheap models)")
        for rank, i in enumerate(sorted(range(len(candidates)), key=lambda i: -ranking[i]), 1):
            params = candidates[i]
            grid = ", ".join(f"{k} {v}" for k, v in params.items() if k not in ("normalise", "derived"))
            say(
                f"    {rank:2d}. {ranking[i]:.3f} (objective {screened[i][0].objective:.3f})  "
                f"{params['normalise']}/{params['derived']}, {grid}  " + ("refined" if i in kept else "dropped")
            )
