"""Calibration on the inner folds of a fold's training recordings (docs/segmentation.md, "How
the parameters are chosen"): each of the last :data:`INNER_FOLDS` training recordings is
validated by a fit on the others; a method's rejection value is the one of the best mean of its
known accuracy and its rejection of pseudo-unknowns (each known class in turn removed from the
model set), and the calibration rule (``calibration``: ``"fallback"``, ``"strict"``) decides
whether it may reject at all.  Fits, states and labels are computed once per fold and shared by
the methods and fidelities that can share them (:class:`InnerFoldCalibration`)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ..base import lagged
from ..datasets import Recording, segments
from ._fidelity import FULL, Fidelity
from ._methods import Fitted
from ._metrics import calibrate, frame_metrics

INNER_FOLDS = 3  # validation recordings of the inner split (each validated by a fit on the others)


PSEUDO_UNKNOWNS = ("refit", "drop")


CALIBRATIONS = ("fallback", "strict")  # the first is the default


REJECT_ALL_OBJECTIVE = 0.5  # mean(known accuracy 0, pseudo-unknown rejection 1)


FALLBACK_MARGIN = 0.05  # an operating point must beat rejecting everything by this much (documented choice)


MIN_TRAINED_CLASSES = 2  # known classes with training segments every training split needs


@dataclass
class Choice:
    """One method's parameters and rejection value chosen on the inner folds."""

    params: dict
    reject: float
    objective: float
    fallback: bool = False  # rejection switched off: nothing beat rejecting everything
    strict: Choice | None = None  # the objective's own choice, when it was overruled

    def selected(self) -> dict:
        """A fold's ``selected`` in the JSON: the parameters, the rejection value, the validation
        objective, whether rejection is off, and the overruled strict choice."""
        out = {
            **self.params,
            "reject": float(self.reject),
            "validation_objective": self.objective,
            "rejection": "off" if self.fallback else "calibrated",
        }
        if self.fallback:
            out["strict"] = {**self.strict.params, "reject": float(self.strict.reject)}
        return out


Split = tuple[Recording, list[Recording]]  # a validation recording and the recordings that train for it


def inner_folds(train: list[Recording]) -> list[Split]:
    """The inner splits of the training recordings ``train``: each of the last :data:`INNER_FOLDS`
    validated by the others."""
    return [(v, [t for t in train if t is not v]) for v in train[-INNER_FOLDS:]]


class InnerFoldCalibration:
    """The calibration part of :class:`._recordings.RecordingsEvaluator`: its fold's cache of fits,
    states and labels (``_cache``), and the calibration of one parameter set at a fidelity."""

    def _segments(self, recs: list[Recording]) -> dict[int, list[np.ndarray]]:
        """Training segments of the known classes that ``recs`` hold; a known class without one is
        left out of the model (its frames elsewhere count as known and are wrong unless labelled
        as it, which that model cannot do).  At least two classes are needed."""
        segs = {c: s for c, s in segments(recs, self.known).items() if s}
        if len(segs) < MIN_TRAINED_CLASSES:
            raise ValueError(
                f"the recordings {[r.name for r in recs]} hold training segments of "
                f"{[self.data.class_names[c] for c in segs] or 'no'} known class(es); every training split of "
                f"leave-one-recording-out needs at least {MIN_TRAINED_CLASSES}: add recordings that hold "
                "more classes or name classes that more recordings hold with --known"
            )
        return segs

    def _untrained(self, recs: list[Recording]) -> list[str]:
        """Names of the known classes without a training segment in ``recs``."""
        return [self.data.class_names[c] for c, segs in segments(recs, self.known).items() if not segs]

    def _calibrated(
        self, method, splits: list[Split], params: dict, fidelity: Fidelity = FULL
    ) -> tuple[Choice, float, Callable]:
        """``params``' best rejection value on ``splits`` (:func:`inner_folds`; the preview: the
        outer folds) at ``fidelity``, the sweep's keep-all value and the known accuracy as a
        function of the rejection value."""
        known_acc, pseudo_rej, grid = self.validation(method, splits, params, fidelity)
        value, score = calibrate(known_acc, pseudo_rej, grid)
        self.detail(f"    {method.name} {fidelity.name} {params}: reject={value:.4g} objective={score:.3f}")
        return Choice(params, value, score), grid[0], known_acc

    def _ranking(self, choices: list[tuple[Choice, float, Callable]]) -> list[float]:
        """What :meth:`_rule` ranks ``choices`` by (the screen of :mod:`._selection` too): the
        objective, or — ``"fallback"``, when none beats rejecting everything by ``FALLBACK_MARGIN``
        — the known accuracy with every frame kept."""
        if not self._falls_back(max(c.objective for c, *_ in choices)):
            return [c.objective for c, *_ in choices]
        return [known_acc(first) for _, first, known_acc in choices]

    def _falls_back(self, objective: float, gate: float | None = None) -> bool:
        """Whether the rule switches rejection off: ``"fallback"`` and neither the best ``objective``
        nor its scorer's ``gate`` beats rejecting everything by ``FALLBACK_MARGIN``."""
        best = min(objective, np.inf if gate is None else gate)
        return self.calibration != "strict" and best <= REJECT_ALL_OBJECTIVE + FALLBACK_MARGIN

    def _rule(self, name: str, choices: list[tuple[Choice, float, Callable]], gate: float | None = None) -> Choice:
        """The calibration rule over a method's calibrated parameter sets: the best objective,
        or — ``"fallback"``, when it does not beat rejecting everything by ``FALLBACK_MARGIN`` —
        rejection off, with the parameters that label the most inner-fold frames right.  ``gate``:
        the best objective of the scorer the method rejects with (``rejects_with``), which must
        beat it too: the method's rejection is off wherever its scorer's is."""
        best = max(choices, key=lambda c: c[0].objective)[0]  # ties: the first
        if not self._falls_back(best.objective, gate):
            return best
        keep_all = [(known_acc(first), Choice(c.params, first, c.objective)) for c, first, known_acc in choices]
        accuracy, chosen = max(keep_all, key=lambda c: c[0])
        self.detail(
            f"    {name}: rejection off (best objective {best.objective:.3f}"
            + ("" if gate is None else f", its scorer's {gate:.3f}")
            + f"); {chosen.params} keeps {accuracy:.3f}"
        )
        return replace(chosen, fallback=True, strict=best)

    def validation(
        self, method, splits: list[Split], params: dict, fidelity: Fidelity = FULL
    ) -> tuple[Callable, Callable, np.ndarray]:
        """The calibration's view of ``method`` with ``params`` on ``splits`` (each a validation
        recording and the recordings that train for it, with ``params``' derived features,
        scaled; the inner folds of :func:`inner_folds`) at ``fidelity``: its known accuracy and
        its pseudo-unknown rejection (mean over the known classes the folds hold) as functions of
        the rejection value, and the values of the method's sweep it tries.  Labels of classes
        outside ``known`` never count: their frames are neither known nor pseudo-unknown."""
        folds = splits
        truth, present = self._known_truth(folds), self.present(folds)
        models = [self.split_models(method, v, rest, params, fidelity, present) for v, rest in folds]
        fits = [(fitted, v) for (fitted, _, _), (v, _) in zip(models, folds)]
        states = [(fitted, state, v) for (fitted, state, _), (v, _) in zip(models, folds)]
        unseen = {
            c: None if any(m[2][c] is None for m in models) else [(*m[2][c], v) for m, (v, _) in zip(models, folds)]
            for c in present
        }

        def pred(r, drop=None):
            if drop is not None and unseen[drop] is not None:  # a model that never saw the class
                return np.concatenate(self._each_split(lambda f, s, v: self._labels(method, f, s, v, r), unseen[drop]))
            return np.concatenate(self._each_split(lambda f, s, v: self._labels(method, f, s, v, r, drop), states))

        @functools.cache
        def known_acc(r):
            return frame_metrics(truth, pred(r), self.known)["known_accuracy"] or 0.0

        def pseudo_rej(r):
            return float(np.mean([np.mean(pred(r, drop=c)[truth == c] == -1) for c in present]))

        return known_acc, pseudo_rej, fidelity.sweep(method.reject_grid(fits[0][0], [s for _, s, _ in states]))

    def _each_split(self, labels: Callable, splits: list[tuple]) -> list[np.ndarray]:
        """``labels(fitted, state, recording)`` of every split, over the threads of ``_threads``
        where there are (the preview's folds; the CLM's sweeps release the GIL), else in turn."""
        if self._threads is None:
            return [labels(*split) for split in splits]
        return list(self._threads.map(lambda split: labels(*split), splits))

    def _labels(self, method, fitted: Fitted, state, rec: Recording, reject: float, drop: int | None = None):
        """``method``'s lagged labels of ``rec`` at ``reject`` (without class ``drop``), computed
        once per fold: the screen's values come back in the refined sweep."""
        key = ("labels", method.name, id(fitted.model), repr(sorted(fitted.params.items())), rec.name, reject, drop)
        if key not in self._cache:
            self._cache[key] = lagged(method.labels(fitted, state, reject, drop=drop), self.lag)
        return self._cache[key]

    def _fit(self, method, train: list[Recording], params: dict, fidelity: Fidelity = FULL) -> Fitted:
        """``method.fit`` on ``train`` at ``fidelity``, shared within a fold by the methods of one
        ``fit_key`` (minirocket and clm_minirocket fit the same classifier on the same data), by
        the parameter sets that differ only in a method's ``label_params`` (used after the fit)
        and by the fidelities whose models are the same."""
        key = self._fit_key(method, params, train, fidelity)
        if key not in self._cache:
            self._cache[key] = method.fit(self._segments(train), params, self.random_state, fidelity)
        return replace(self._cache[key], params=params)

    @staticmethod
    def _fit_key(method, params: dict, train: list[Recording], fidelity: Fidelity) -> tuple:
        """What identifies a fitted model: the fidelity only where it changes one (``cheaper_fits``)."""
        fit_params = {k: v for k, v in params.items() if k not in getattr(method, "label_params", ())}
        models = fidelity.models if method.cheaper_fits else None
        return (method.fit_key, repr(sorted(fit_params.items())), tuple(r.name for r in train), models)

    def _split_key(self, method, v: Recording, rest: list[Recording], params: dict, fidelity: Fidelity, present):
        """What identifies one split's models (:meth:`split_models`): the fit's key, how the
        fidelity treats pseudo-unknowns, the validation recording and the classes it holds."""
        fit = self._fit_key(method, params, rest, fidelity)
        return ("split", *fit, fidelity.pseudo_unknowns, v.name, tuple(present))

    def _known_truth(self, splits: list[Split]) -> np.ndarray:
        """The validation recordings' labels of known classes (others −1: they never count)."""
        return np.concatenate([np.where(np.isin(v.y, self.known), v.y, -1) for v, _ in splits])

    def present(self, splits: list[Split]) -> list[int]:
        """The known classes the validation recordings of ``splits`` hold (the pseudo-unknowns)."""
        truth = self._known_truth(splits)
        return [c for c in self.known if np.any(truth == c)]

    def split_models(
        self, method, v: Recording, rest: list[Recording], params: dict, fidelity: Fidelity, present: list[int]
    ) -> tuple[Fitted, object, dict[int, tuple | None]]:
        """What the calibration needs of one split: ``method`` with ``params`` fitted on ``rest``
        at ``fidelity``, its state on ``v``, and per class of ``present`` a model that never saw
        it with its state (:meth:`~._methods.ScoreMethod.without_class`; the model itself where
        the split never held the class), or None where dropping the class is exact or the
        evaluation or ``fidelity`` drops classes (``pseudo_unknowns="drop"``).  Computed once per
        fold, or by the preview's workers (:meth:`._preview.PreviewRunner._warm`)."""
        key = self._split_key(method, v, rest, params, fidelity, present)
        if key not in self._cache:
            fitted = self._fit(method, rest, params, fidelity)
            unseen = {c: self._unseen(method, fitted, rest, v, params, c, fidelity) for c in present}
            self._cache[key] = (fitted, self._prepare(method, fitted, v), unseen)
        fitted, state, unseen = self._cache[key]
        return (
            replace(fitted, params=params),
            state,
            {c: None if u is None else (replace(u[0], params=params), u[1]) for c, u in unseen.items()},
        )

    def _unseen(self, method, fitted: Fitted, rest, v: Recording, params: dict, drop: int, fidelity: Fidelity):
        """One split's model without class ``drop`` and its state on ``v`` (:meth:`split_models`)."""
        if "drop" in (self.pseudo_unknowns, fidelity.pseudo_unknowns):
            return None
        if drop not in fitted.classes:  # this split never held the class: the model is one
            return fitted, self._prepare(method, fitted, v)
        key = (*self._fit_key(method, params, rest, fidelity), "without", drop)
        if key not in self._cache:
            self._cache[key] = method.without_class(fitted, self._segments(rest), drop, self.random_state)
        if self._cache[key] is None:
            return None
        refit = replace(self._cache[key], params=params)
        return refit, self._prepare(method, refit, v)

    def _prepare(self, method, fitted: Fitted, rec: Recording):
        key = (method.fit_key, id(fitted.model), rec.name)
        if key not in self._cache:
            self._cache[key] = method.prepare(fitted, rec.X)
        return self._cache[key]
