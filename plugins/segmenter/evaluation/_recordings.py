"""Leave-one-recording-out evaluation on continuous recordings (docs/segmentation.md).

For each held-out recording: the other recordings are the training data.  Parameters of every
method — its hyper-parameters (:meth:`grid`) and its rejection parameter — are chosen on inner
splits of those only, by the mean of
``known_accuracy`` and the rejection of pseudo-unknowns (each known class in turn removed from the
model set, its frames then count as unknown; ``pseudo_unknowns="refit"`` refits a classifier
fitted on all classes at once without the class, ``"drop"`` only drops its decision column),
pooled over inner folds that each hold out one of
the last ``INNER_FOLDS`` training recordings.  The method is refitted on all training recordings
and labels the held-out one frame by frame.  Frames of labels outside ``known`` are never used for
training or calibration; every figure is computed on frames pooled over the folds.

Derived features (``derived``, :mod:`..features`) are appended to every recording before the
scaling and chosen on the same inner splits, per method, as one more parameter.  When no operating
point beats rejecting everything on validation by more than ``FALLBACK_MARGIN``,
``calibration="fallback"`` (the default) switches rejection off for that method and fold and takes
the parameters that label the most validation frames right; ``"strict"`` keeps the objective's
choice whatever it is (docs/segmentation.md).  :func:`calibrate_background` and
:func:`calibrate_null_score` apply the same rule to the models ``train-classes`` and the scorers
``fit-scorer`` write for the online node.

``lag`` labels each frame from the evidence of the window ending ``lag`` frames later
(:func:`..base.lagged`), in the calibration as in the figures; every method is also reported at
lag 0 and at half its causal window (``open_set_accuracy_at_lag``).

Every recording is scaled with the fold's training frames (``normalise``): z-scored with their
mean and standard deviation (``"training"``), or each recording standardised causally with its
own running statistics and those as the prior (``"recording"``, :mod:`..features`); given several,
the normalisation is chosen like the derived features, per method and fold, on the inner splits
(every method alike gets the same choices; ties keep the first).  ``ukr_clm_online`` feeds the normalised held-out
recording sample by sample through :class:`OnlineCLMSegmenter` with the parameters selected for
``ukr_clm`` and keeps each sample's final published label; its ``agreement`` is the share of
frames equal to the batch ``ukr_clm``.

Folds are independent (each starts its own model cache and every fit takes ``random_state``), so
``jobs`` > 1 runs them over that many forked processes, with the same figures as one after the
other; BLAS runs one thread either way, as the sums of a multi-threaded BLAS (the HMMs',
MiniRocket's) can differ in the last bits (docs/segmentation.md, ``--jobs``).

``checkpoints`` (a directory) keeps every finished fold and takes those of an earlier run with
the same recordings and settings from there (:mod:`._checkpoints`).

``enroll`` = K ≥ 1 refits every method with the first K segments per known class of the
held-out recording (``enrol_adaptations``: aligning every recording by its own enrolment, or not,
or whichever of those and no enrolment labels the inner folds' frames after their own enrolment
best) and scores both fits on the frames after them (:mod:`._enrolment`).
"""

from __future__ import annotations

import functools
import multiprocessing
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass, field, replace

import numpy as np
from threadpoolctl import threadpool_limits

from .._moved import renamed
from ..base import lagged
from ..datasets import ADAPTATIONS, Recording, RecordingSet, enrolment_split, segments
from ..features import DERIVED, ChannelScaling, RunningStandardizer, derive
from ._checkpoints import FoldCheckpoints, settings_digest
from ._enrolment import (
    CHOSEN,
    ENROL_CHOICES,
    ENROL_MARGIN,
    EVALUATION_ADAPTATIONS,
    check_enrolment,
    enrolled,
    enrolled_views,
    enrolment_report,
    fold_note,
)
from ._methods import REGISTRY, Fitted, UKRCLMMethod
from ._metrics import calibrate, frame_metrics, segment_f1, tradeoff_curve
from ._selection import FULL, REFINE, SCREEN, Fidelity, first_of_best, survivors

INNER_FOLDS = 3  # validation recordings of the inner split (each validated by a fit on the others)
DEFAULT_METHODS = ("ukr_clm", "ukr_clm_online", "ukr_only", "dtw_1nn", "hmm", "minirocket", "clm_minirocket")
NORMALISATIONS = ("training", "recording")
NORMALISATION_DESCRIPTIONS = {
    "training": "z-score with the fold's training frames (every method)",
    "recording": "each recording standardised causally, prior = the fold's training frames (every method)",
}
PSEUDO_UNKNOWNS = ("refit", "drop")
CALIBRATIONS = ("fallback", "strict")  # the first is the default
REJECT_ALL_OBJECTIVE = 0.5  # mean(known accuracy 0, pseudo-unknown rejection 1)
FALLBACK_MARGIN = 0.05  # an operating point must beat rejecting everything by this much (documented choice)
MIN_TRAINED_CLASSES = 2  # known classes with training segments every training split needs


def default_jobs() -> int:
    """The number of cores this process may run on (the default of ``--jobs``)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


_FORKED: RecordingsEvaluator | None = None  # the evaluator whose folds the forked workers run


def _one_thread() -> None:
    """A worker's start: its BLAS/OpenMP pools get one thread, so ``jobs`` workers use ``jobs`` cores."""
    threadpool_limits(1)


def _forked_fold(k: int, held: str) -> FoldResult:
    return _FORKED._announced_fold(k, held)


@dataclass
class FoldResult:
    recording: str
    truth: np.ndarray
    labels: dict[str, np.ndarray]
    selected: dict[str, dict]
    sweeps: dict[str, list[np.ndarray]]  # per method: labels at every rejection value of its sweep
    strict: dict[str, np.ndarray]  # per method that fell back: the labels at the strict choice
    untrained: list[str]  # known classes without a training segment in this fold
    unlagged: dict[str, np.ndarray]  # per method: the labels at lag 0 (``labels`` are at the evaluation's lag)
    enrolled: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)  # per adaptation, method: labels
    scored_from: int = 0  # the first frame after the enrolment
    seconds: float = 0.0  # the fold's own wall time
    timing: dict[str, dict[str, float]] = field(default_factory=dict)  # method → phase → seconds


@dataclass
class Choice:
    """One method's parameters and rejection value chosen on the inner folds."""

    params: dict
    reject: float
    objective: float
    fallback: bool = False  # rejection switched off: nothing beat rejecting everything
    strict: Choice | None = None  # the objective's own choice, when it was overruled


def inner_folds(train: list[Recording]) -> list[tuple[Recording, list[Recording]]]:
    """The inner splits of the training recordings ``train``: each of the last :data:`INNER_FOLDS`
    validated by the others."""
    return [(v, [t for t in train if t is not v]) for v in train[-INNER_FOLDS:]]


def _zscore(train: list[Recording], recs: list[Recording], normalise: str = "training") -> list[Recording]:
    """``recs`` z-scored with the mean and standard deviation of the frames of ``train``
    (``"training"``) or causally with running ones, each recording on its own, those frames being
    the prior (``"recording"``, :class:`..features.RunningStandardizer`)."""
    if normalise == "training":
        scaler = ChannelScaling().fit([r.X for r in train])
    else:
        scaler = RunningStandardizer().fit(np.vstack([r.X for r in train]))
    return [Recording(r.name, scaler.transform(r.X), r.y) for r in recs]


def _degenerate_calibration(
    truth: np.ndarray, pred: np.ndarray, known: list[int], selected: list[dict], no_rejection: dict | None
) -> str | None:
    """What a user needs to know when the calibration chose to reject (nearly) every known frame
    because, on validation, nothing did better than rejecting everything; ``None`` otherwise."""
    is_known = np.isin(truth, known)
    rejected = float(np.mean(pred[is_known] == -1)) if is_known.any() else 0.0
    best = max(s.get("validation_objective", 1.0) for s in selected)
    if rejected < 0.9 or best > REJECT_ALL_OBJECTIVE + FALLBACK_MARGIN:
        return None
    return (
        f"{rejected:.0%} of the known frames are rejected: on the inner folds no operating point kept "
        f"known frames and rejected left-out classes better than rejecting everything (best validation "
        f"objective {best:.3f}; rejecting everything scores {REJECT_ALL_OBJECTIVE}). The classes are not "
        "separable enough here for open-set rejection"
        + (
            f"; without rejection {no_rejection['known_accuracy']:.3f} of the known frames are right ('no_rejection')"
            if no_rejection and no_rejection.get("known_accuracy") is not None
            else ""
        )
        + "; the default calibration (fallback) switches rejection off in that case"
    )


def _fallback_note(folds: int, fell_back: int, strict: dict | None) -> str | None:
    """What a user needs to know when the calibration switched rejection off in some folds;
    ``None`` when it never did."""
    if not fell_back:
        return None
    return (
        f"rejection is off in {fell_back} of {folds} folds: on the inner folds no operating point kept known "
        f"frames and rejected left-out classes better than rejecting everything (objective <= "
        f"{REJECT_ALL_OBJECTIVE + FALLBACK_MARGIN:.2f}; rejecting everything scores {REJECT_ALL_OBJECTIVE}), so the "
        "classes are not separable enough here for open-set rejection and every frame keeps its best label"
        + (
            f"; the objective's own choice would label {strict['open_set_accuracy']:.3f} of the frames right ('strict')"
            if strict and strict.get("open_set_accuracy") is not None
            else ""
        )
    )


def choice_summary(selected: dict) -> str:
    """A method's choice in a fold, for the progress line: view, grid point, rejection, objective."""
    grid = ", ".join(f"{k} {v}" for k, v in selected.items() if k not in _NOT_GRID)
    rejection = "rejection off" if selected["rejection"] == "off" else f"reject {selected['reject']:.3g}"
    return (
        f"{selected['normalise']}/{selected['derived']}, {grid}, {rejection} "
        f"(validation {selected['validation_objective']:.3f})"
    )


_NOT_GRID = (
    "normalise",
    "derived",
    "reject",
    "validation_objective",
    "rejection",
    "strict",
    "enrol_adaptation",
    "enrol_validation",
)


def _timing(folds: list[FoldResult]) -> dict:
    """Seconds per method and phase (selection, final fit, labelling), summed over the folds, and
    each fold's wall time: the JSON's ``timing`` (on the machine of the run, unlike the figures)."""
    per_method: dict[str, dict[str, float]] = {}
    for fold in folds:
        for name, phases in fold.timing.items():
            for phase, seconds in phases.items():
                per_method.setdefault(name, {}).setdefault(phase, 0.0)
                per_method[name][phase] += seconds
    return {
        "methods": {n: {p: round(v, 2) for p, v in phases.items()} for n, phases in per_method.items()},
        "folds": {f.recording: round(f.seconds, 2) for f in folds},
    }


def half_window(selected: dict) -> int:
    """Half the causal window behind a method's labels, in frames: the ``window`` of a scorer
    (MiniRocket, DTW, HMM; the scorer's for the CLM over it) or the ``delay`` window of the
    manifold methods (docs/segmentation.md, "Labels with a lag")."""
    return int(selected.get("window", selected.get("delay", 0))) // 2


class RecordingsEvaluator:
    """Runs the leave-one-recording-out protocol for the chosen methods."""

    def __init__(
        self,
        data: RecordingSet,
        known: list[str] | None = None,
        methods: tuple[str, ...] = DEFAULT_METHODS,
        quick: bool = False,
        random_state: int = 0,
        progress: Callable[[str], None] = lambda msg: None,
        normalise: str | tuple[str, ...] = "training",
        pseudo_unknowns: str = "refit",
        derived: tuple[str, ...] = ("none",),
        calibration: str = CALIBRATIONS[0],
        lag: int = 0,
        jobs: int = 1,
        enroll: int = 0,
        enrol_adaptations: tuple[str, ...] = EVALUATION_ADAPTATIONS[:1],
        checkpoints: str | None = None,
        detail: Callable[[str], None] = lambda msg: None,
    ) -> None:
        if jobs < 1:
            raise ValueError(f"jobs must be at least 1, got {jobs}")
        normalise = (normalise,) if isinstance(normalise, str) else tuple(normalise)
        if not normalise or len(set(normalise)) != len(normalise) or not set(normalise) <= set(NORMALISATIONS):
            raise ValueError(f"normalise must be one of {NORMALISATIONS} (or distinct ones), got {list(normalise)}")
        if pseudo_unknowns not in PSEUDO_UNKNOWNS:
            raise ValueError(f"pseudo_unknowns must be one of {PSEUDO_UNKNOWNS}, got {pseudo_unknowns!r}")
        if calibration not in CALIBRATIONS:
            raise ValueError(f"calibration must be one of {CALIBRATIONS}, got {calibration!r}")
        if lag < 0:
            raise ValueError(f"lag must be >= 0 frames, got {lag}")
        if not derived or len(set(derived)) != len(derived) or not set(derived) <= set(DERIVED):
            raise ValueError(f"derived features: name distinct choices among {DERIVED}, got {list(derived)}")
        unknown_names = sorted(set(known or []) - set(data.class_names))
        if unknown_names:
            raise ValueError(f"--known names classes {unknown_names} that the data lacks; it has {data.class_names}")
        bad = sorted(set(methods) - set(REGISTRY))
        if bad:
            raise ValueError(f"unknown methods {bad}; choose from {sorted(REGISTRY)}")
        batches = [REGISTRY[m].batch.name for m in methods if REGISTRY[m].batch is not None]
        methods = (*dict.fromkeys(b for b in batches if b not in methods), *methods)
        if len(data.recordings) < 3:
            raise ValueError("leave-one-recording-out needs at least 3 recordings (2 to train and validate, 1 to test)")
        self.data = data
        self.known = [data.class_names.index(k) for k in known] if known else list(range(len(data.class_names)))
        check_enrolment(data, self.known, enroll, enrol_adaptations)
        self.enroll = enroll
        self.enrol_adaptations = tuple(enrol_adaptations)
        self.methods = methods
        self.quick = quick
        self.random_state = random_state
        self.progress = progress
        self.detail = detail  # every calibrated candidate (``--verbose``)
        self.normalise = normalise
        self.pseudo_unknowns = pseudo_unknowns
        self.derived = tuple(derived)
        self.calibration = calibration
        self.lag = lag
        self.jobs = jobs
        self.checkpoints = checkpoints
        self._cache: dict[tuple, object] = {}
        self._fold_choices: dict[str, list] = {}  # method → its calibrated parameter sets in this fold
        self._timing: dict[str, dict[str, float]] = {}  # method → phase → seconds, in this fold

    # -- one fold ---------------------------------------------------------------------------
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

    def _select(self, name: str, views: dict[tuple[str, str], list[Recording]]) -> Choice:
        """Normalisation, derived features, hyper-parameters and rejection value of one method, chosen
        on inner splits of the training recordings (``views``: (normalisation, derived) → those recordings)."""
        method = REGISTRY[name]
        gate = (
            None
            if method.rejects_with is None
            else max(c.objective for c, *_ in self._choices(method.rejects_with, views))
        )
        return self._rule(name, self._choices(method, views), gate)

    def _choices(self, method, views: dict[tuple[str, str], list[Recording]]) -> list[tuple[Choice, float, Callable]]:
        """The parameter sets of ``method`` (normalisation and derived features included) that
        survive the screen, calibrated on the inner folds (:mod:`._selection`); once per fold,
        whether for the method itself or as the scorer another method rejects with."""
        if method.name not in self._fold_choices:
            candidates = [
                (train, {**params, "derived": derived, "normalise": normalise})
                for (normalise, derived), train in views.items()
                for params in method.grid(self.quick)
            ]
            if len(candidates) > 1:
                screened = [self._calibrated(method, train, params, SCREEN)[0] for train, params in candidates]
                candidates = [candidates[i] for i in survivors([c.objective for c in screened])]
            self._fold_choices[method.name] = [
                self._calibrated(method, train, params, REFINE) for train, params in candidates
            ]
        return self._fold_choices[method.name]

    def _calibrated(
        self, method, train: list[Recording], params: dict, fidelity: Fidelity = FULL
    ) -> tuple[Choice, float, Callable]:
        """``params``' best rejection value on the inner folds of ``train`` at ``fidelity``, the
        sweep's keep-all value and the known accuracy as a function of the rejection value."""
        known_acc, pseudo_rej, grid = self.validation(method, train, params, fidelity)
        value, score = calibrate(known_acc, pseudo_rej, grid)
        self.detail(f"    {method.name} {fidelity.name} {params}: reject={value:.4g} objective={score:.3f}")
        return Choice(params, value, score), grid[0], known_acc

    def _rule(self, name: str, choices: list[tuple[Choice, float, Callable]], gate: float | None = None) -> Choice:
        """The calibration rule over a method's calibrated parameter sets: the best objective,
        or — ``"fallback"``, when it does not beat rejecting everything by ``FALLBACK_MARGIN`` —
        rejection off, with the parameters that label the most inner-fold frames right.  ``gate``:
        the best objective of the scorer the method rejects with (``rejects_with``), which must
        beat it too: the method's rejection is off wherever its scorer's is."""
        best = choices[first_of_best([c.objective for c, *_ in choices])][0]
        separable = min(best.objective, np.inf if gate is None else gate) > REJECT_ALL_OBJECTIVE + FALLBACK_MARGIN
        if self.calibration == "strict" or separable:
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
        self, method, train: list[Recording], params: dict, fidelity: Fidelity = FULL
    ) -> tuple[Callable, Callable, np.ndarray]:
        """The calibration's view of ``method`` with ``params`` on the inner folds of ``train``
        (recordings with ``params``' derived features, scaled) at ``fidelity``: its known accuracy
        and its pseudo-unknown rejection (mean over the known classes the folds hold) as
        functions of the rejection value, and the values of the method's sweep it tries."""
        folds = inner_folds(train)
        truth = np.concatenate([np.where(np.isin(v.y, self.known), v.y, -1) for v, _ in folds])
        present = [c for c in self.known if np.any(truth == c)]
        fits = [(self._fit(method, rest, params, fidelity), v) for v, rest in folds]
        states = [(f, self._prepare(method, f, v), v) for f, v in fits]
        unseen = {c: self._without(method, fits, folds, params, c, fidelity) for c in present}

        def pred(r, drop=None):
            if drop is not None and unseen[drop] is not None:  # a model that never saw the class
                return np.concatenate([self._labels(method, f, s, v, r) for f, s, v in unseen[drop]])
            return np.concatenate([self._labels(method, f, s, v, r, drop) for f, s, v in states])

        @functools.cache
        def known_acc(r):
            return frame_metrics(truth, pred(r), self.known)["known_accuracy"] or 0.0

        def pseudo_rej(r):
            return float(np.mean([np.mean(pred(r, drop=c)[truth == c] == -1) for c in present]))

        return known_acc, pseudo_rej, fidelity.sweep(method.reject_grid(fits[0][0], [s for _, s, _ in states]))

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
        fit_params = {k: v for k, v in params.items() if k not in getattr(method, "label_params", ())}
        return (method.fit_key, repr(sorted(fit_params.items())), tuple(r.name for r in train), fidelity.models)

    def _without(self, method, fits, folds, params: dict, drop: int, fidelity: Fidelity) -> list | None:
        """Per inner fold the model, validation state and recording of ``method`` fitted without
        class ``drop`` (:meth:`~._methods.ScoreMethod.without_class`), or None where dropping it
        is exact or the evaluation or ``fidelity`` drops classes (``pseudo_unknowns="drop"``)."""
        if "drop" in (self.pseudo_unknowns, fidelity.pseudo_unknowns):
            return None
        unseen = []
        for (fitted, v), (_, rest) in zip(fits, folds):
            if drop not in fitted.classes:  # this inner split never held the class: the model is one
                unseen.append((fitted, self._prepare(method, fitted, v), v))
                continue
            key = (*self._fit_key(method, params, rest, fidelity), "without", drop)
            if key not in self._cache:
                self._cache[key] = method.without_class(fitted, self._segments(rest), drop, self.random_state)
            if self._cache[key] is None:
                return None
            refit = replace(self._cache[key], params=params)
            unseen.append((refit, self._prepare(method, refit, v), v))
        return unseen

    def _prepare(self, method, fitted: Fitted, rec: Recording):
        key = (method.fit_key, id(fitted.model), rec.name)
        if key not in self._cache:
            self._cache[key] = method.prepare(fitted, rec.X)
        return self._cache[key]

    def fold_views(self, held: str | None) -> dict[tuple[str, str], tuple[list[Recording], Recording | None]]:
        """Per (normalisation, derived features) choice: the training recordings and the held-out one
        (None: all recordings train), with the features appended and then scaled with the training
        frames.  Starts the fold: fitted models and states of the previous one are dropped."""
        self._cache.clear()
        views = {}
        for derived in self.derived:
            recs = [Recording(r.name, derive(r.X, derived), r.y) for r in self.data.recordings]
            for normalise in self.normalise:
                scaled = _zscore([r for r in recs if r.name != held], recs, normalise)
                views[normalise, derived] = (
                    [r for r in scaled if r.name != held],
                    next((r for r in scaled if r.name == held), None),
                )
        return views

    def run_fold(self, held: str) -> FoldResult:
        views = self.fold_views(held)
        untrained = self._untrained(self.data.without(held))
        if untrained:
            self.progress(
                f"  {held}: no training segment of {untrained} in the other recordings; models leave them out"
            )
        labels, selected, sweeps, strict = {}, {}, {}, {}
        self._fold_choices, self._timing = {}, {}
        sessions = {a: enrolled_views(views, self.known, self.enroll, a) for a in ADAPTATIONS if self.enroll}
        with_enrolment = {a: {} for a in self.enrol_adaptations if self.enroll}

        def lag(x: np.ndarray) -> np.ndarray:
            return lagged(x, self.lag)

        for name in self.methods:
            if REGISTRY[name].batch is not None:
                continue  # replayed with the models of its batch method, below
            t0 = time.perf_counter()
            with self._timed(name, "selection"):
                choice = self._select(name, {key: train for key, (train, _) in views.items()})
            method = REGISTRY[name]
            fitted, state, test = self._final(method, choice.params, views)
            with self._timed(name, "labelling"):
                labels[name] = method.labels(fitted, state, choice.reject)
                sweeps[name] = [lag(method.labels(fitted, state, r)) for r in method.reject_grid(fitted, [state])]
            selected[name] = {
                **choice.params,
                "reject": float(choice.reject),
                "validation_objective": choice.objective,
                "rejection": "off" if choice.fallback else "calibrated",
            }
            if choice.fallback:
                selected[name]["strict"] = {**choice.strict.params, "reject": float(choice.strict.reject)}
                strict_fit, strict_state, _ = self._final(method, choice.strict.params, views)
                with self._timed(name, "labelling"):
                    strict[name] = lag(method.labels(strict_fit, strict_state, choice.strict.reject))
            if CHOSEN in with_enrolment:
                with self._timed(name, "selection"):
                    selected[name]["enrol_adaptation"], selected[name]["enrol_validation"] = self._adaptation(
                        method, choice, views
                    )
            self.progress(f"  {held}: {name} {choice_summary(selected[name])} in {time.perf_counter() - t0:.1f} s")
            self.detail(f"    {name}: {selected[name]}")
            for online in map(REGISTRY.get, self._replaying(method)):
                t0 = time.perf_counter()
                with self._timed(online.name, "labelling"):
                    labels[online.name] = online.labels_online(fitted, choice.reject, test.X)
                selected[online.name] = selected[name]
                self.progress(f"  {held}: {online.name} replayed {name}'s models in {time.perf_counter() - t0:.1f} s")
            for adaptation in with_enrolment:
                chosen = selected[name]["enrol_adaptation"] if adaptation == CHOSEN else adaptation
                with_enrolment[adaptation].update(
                    {m: lag(labels[m]) for m in (name, *self._replaying(method))}
                    if chosen == "none"
                    else self._enrolled(method, choice, sessions[chosen])
                )
        lagged_labels = {name: lag(x) for name, x in labels.items()}
        truth = next(iter(views.values()))[1].y
        scored_from = enrolment_split(truth, self.known, self.enroll)[1] if self.enroll else 0
        return FoldResult(
            held,
            truth,
            lagged_labels,
            selected,
            sweeps,
            strict,
            untrained,
            labels,
            with_enrolment,
            scored_from,
            timing=self._timing,
        )

    @contextmanager
    def _timed(self, name: str, phase: str):
        """Adds the wall time of the block to ``name``'s ``phase`` in this fold's timing."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            phases = self._timing.setdefault(name, {})
            phases[phase] = phases.get(phase, 0.0) + time.perf_counter() - t0

    def _enrolled(self, method, choice: Choice, session: dict) -> dict[str, np.ndarray]:
        """The lagged labels of the held-out recording by ``method`` (and the online methods that
        replay its models) with ``choice``, fitted with the enrolment (``session``:
        :func:`._enrolment.enrolled_views`)."""
        fitted, state, test = self._final(method, choice.params, session)
        out = {method.name: method.labels(fitted, state, choice.reject)}
        for online in map(REGISTRY.get, self._replaying(method)):
            out[online.name] = online.labels_online(fitted, choice.reject, test.X)
        return {name: lagged(x, self.lag) for name, x in out.items()}

    def _replaying(self, method) -> list[str]:
        """The online methods of this evaluation that replay ``method``'s models."""
        return [m for m in self.methods if REGISTRY[m].batch is method]

    def _adaptation(self, method, choice: Choice, views) -> tuple[str, dict[str, float]]:
        """The enrolment adaptation (:data:`._enrolment.ENROL_CHOICES`) of ``method`` with
        ``choice``, and each one's open-set accuracy on the inner folds' frames after their own
        enrolment (pooled): each inner validation recording enrols as the held-out one does,
        refitted on the other training recordings.  The best one, if it beats no enrolment by
        :data:`._enrolment.ENROL_MARGIN` (ties keep the first); no enrolment otherwise."""
        train = views[choice.params["normalise"], choice.params["derived"]][0]
        folds = inner_folds(train)
        starts = [enrolment_split(v.y, self.known, self.enroll)[1] for v, _ in folds]
        truth = np.concatenate([v.y[s:] for (v, _), s in zip(folds, starts)])
        scores = {}
        for adaptation in ENROL_CHOICES:
            pred = []
            for (v, rest), start in zip(folds, starts):
                fit_on, test = enrolled(rest, v, self.known, self.enroll, adaptation)
                fitted = self._fit(method, fit_on, choice.params, REFINE)
                labels = method.labels(fitted, self._prepare(method, fitted, test), choice.reject)
                pred.append(lagged(labels, self.lag)[start:])
            scores[adaptation] = frame_metrics(truth, np.concatenate(pred), self.known)["open_set_accuracy"] or 0.0
        best = max(ENROL_CHOICES, key=scores.get)
        if scores[best] < scores[ENROL_CHOICES[0]] + ENROL_MARGIN:
            best = ENROL_CHOICES[0]
        self.progress(
            f"    {method.name}: enrolment {best} ("
            + ", ".join(f"{a} {score:.3f}" for a, score in scores.items())
            + f" on the inner folds' frames after their enrolment; an adaptation must gain {ENROL_MARGIN})"
        )
        return best, scores

    def _final(self, method, params: dict, views) -> tuple:
        """``method`` fitted with ``params`` on all training recordings, its state on the held-out
        recording and that recording as the method sees it (with ``params``' normalisation and
        derived features)."""
        train, test = views[params["normalise"], params["derived"]]
        with self._timed(method.name, "final_fit"):
            fitted = self._fit(method, train, params)
        with self._timed(method.name, "labelling"):
            return fitted, self._prepare(method, fitted, test), test

    # -- all folds --------------------------------------------------------------------------
    def _announced_fold(self, k: int, held: str) -> FoldResult:
        self.progress(f"fold {k + 1}/{len(self.data.recordings)}: holding out '{held}'")
        t0 = time.perf_counter()
        fold = replace(self.run_fold(held), seconds=time.perf_counter() - t0)
        if self.enroll:
            self.progress(f"  {fold_note(fold, self.known)}")
        return fold

    def _run_folds(self) -> list[FoldResult]:
        """Every fold's result in recording order: one after the other, or over ``jobs`` forked
        processes (module docstring); progress per fold either way."""
        global _FORKED
        names, start, done = self.data.names(), time.perf_counter(), {}
        kept = self._checkpoints()
        for held in names if kept else ():
            if (fold := kept.load(held)) is not None:
                done[held] = fold
                self.progress(f"fold '{held}' taken from {kept.path(held)}")
        todo = [(k, held) for k, held in enumerate(names) if held not in done]

        def finished(held: str, fold: FoldResult) -> None:
            done[held] = fold
            computed.append(fold.seconds)
            if kept:
                kept.save(fold)
            spent, left = time.perf_counter() - start, len(names) - len(done)
            if left:  # folds differ in size: their mean so far, over the workers, is the estimate
                self.progress(
                    f"fold '{held}' done ({len(done)}/{len(names)}); {spent / 60:.1f} min so far, "
                    f"about {np.mean(computed) * left / min(jobs, left) / 60:.0f} min to go"
                )

        computed: list[float] = []  # wall times of the folds computed in this run
        jobs = min(self.jobs, len(todo))
        if jobs <= 1:
            with threadpool_limits(1):  # as in a worker: BLAS sums in the same order whatever ``jobs``
                for k, held in todo:
                    finished(held, self._announced_fold(k, held))
            return [done[h] for h in names]
        _FORKED = self
        try:
            context = multiprocessing.get_context("fork")
            with ProcessPoolExecutor(jobs, mp_context=context, initializer=_one_thread) as pool:
                futures = {pool.submit(_forked_fold, k, held): held for k, held in todo}
                try:
                    for future in as_completed(futures):
                        finished(futures[future], future.result())
                finally:  # a fold failed: the folds not yet started are not run
                    pool.shutdown(cancel_futures=True)
        finally:
            _FORKED = None
        return [done[h] for h in names]

    def _checkpoints(self) -> FoldCheckpoints | None:
        """The store of finished folds (``checkpoints``), keyed by the data and every setting that
        moves a figure; None without one."""
        if not self.checkpoints:
            return None
        settings = {k: v for k, v in self._parameters().items() if k != "dataset"}
        settings.update(methods=list(self.methods), random_state=self.random_state)
        digest = settings_digest(self.data.recordings, self.data.class_names, settings)
        return FoldCheckpoints(self.checkpoints, digest, FoldResult, self.progress)

    def evaluate(self) -> dict:
        folds = self._run_folds()
        truth = np.concatenate([f.truth for f in folds])
        out: dict = {"methods": {}, "parameters": self._parameters()}
        for name in self.methods:
            pred = np.concatenate([f.labels[name] for f in folds])
            res = frame_metrics(truth, pred, self.known)
            res["segment_f1"] = segment_f1([(f.truth, f.labels[name]) for f in folds], self.known)
            res.update(self._at_lags(folds, name, truth))
            res["tradeoff_auc"] = None
            if name in folds[0].sweeps:  # the first value of every sweep keeps every frame
                res["no_rejection"] = frame_metrics(
                    truth, np.concatenate([f.sweeps[name][0] for f in folds]), self.known
                )
            fell_back = [f for f in folds if name in f.strict]
            res["rejection_off_folds"] = len(fell_back)
            if fell_back:  # the objective's own choice, for the folds where it was overruled
                strict = np.concatenate([f.strict.get(name, f.labels[name]) for f in folds])
                res["strict"] = frame_metrics(truth, strict, self.known)
            res["calibration_note"] = _fallback_note(len(folds), len(fell_back), res.get("strict")) or (
                _degenerate_calibration(
                    truth, pred, self.known, [f.selected[name] for f in folds], res.get("no_rejection")
                )
            )
            if name in folds[0].sweeps and res["unknown_rejection"] is not None:
                res["tradeoff"] = self._tradeoff(folds, name, truth)
                res["tradeoff_auc"] = res["tradeoff"]["auc"]
            res["folds"] = [
                {
                    "recording": f.recording,
                    "untrained_classes": f.untrained,
                    "selected": f.selected[name],
                    **frame_metrics(f.truth, f.labels[name], self.known),
                    "segment_f1": segment_f1([(f.truth, f.labels[name])], self.known),
                    "half_window": half_window(f.selected[name]),
                }
                for f in folds
            ]
            if REGISTRY[name].batch is not None:
                batch = np.concatenate([f.labels[REGISTRY[name].batch.name] for f in folds])
                res["agreement"] = float(np.mean(pred == batch))
            if self.enroll:
                res["enrolment"] = enrolment_report(folds, name, self.known, self.enrol_adaptations)
            out["methods"][name] = res
        out["timing"] = _timing(folds)
        self.folds_ = folds
        return out

    def _at_lags(self, folds: list[FoldResult], name: str, truth: np.ndarray) -> dict:
        """Open-set frame accuracy and segment F1 at lag 0 and at half the method's causal window
        (per fold, :func:`half_window`): the latency/accuracy trade of :func:`..base.lagged`."""
        out: dict = {"open_set_accuracy_at_lag": {}, "segment_f1_at_lag": {}}
        for key, lag_of in (("0", lambda f: 0), ("half_window", lambda f: half_window(f.selected[name]))):
            pairs = [(f.truth, lagged(f.unlagged[name], lag_of(f))) for f in folds]
            out["open_set_accuracy_at_lag"][key] = frame_metrics(
                truth, np.concatenate([p for _, p in pairs]), self.known
            )["open_set_accuracy"]
            out["segment_f1_at_lag"][key] = segment_f1(pairs, self.known)
        return out

    def _tradeoff(self, folds: list[FoldResult], name: str, truth: np.ndarray) -> dict:
        n = min(len(f.sweeps[name]) for f in folds)
        acc, rej = [], []
        for i in range(n):  # the i-th value of every fold's own sweep (sweeps run from keep-all to reject-all)
            pred = np.concatenate([f.sweeps[name][round(i * (len(f.sweeps[name]) - 1) / max(n - 1, 1))] for f in folds])
            m = frame_metrics(truth, pred, self.known)
            acc.append(m["known_accuracy"] or 0.0)
            rej.append(m["unknown_rejection"] or 0.0)
        r, a, auc = tradeoff_curve(acc, rej)
        return {"unknown_rejection": r, "known_accuracy": a, "auc": auc}

    def _parameters(self) -> dict:
        return {
            "protocol": f"leave-one-recording-out; inner folds hold out each of the last {INNER_FOLDS} training recordings",
            "known": [self.data.class_names[c] for c in self.known],
            "classes": self.data.class_names,
            "recordings": self.data.names(),
            "dataset": self.data.source,
            "normalisation": self._normalisation(),
            "pseudo_unknowns": self.pseudo_unknowns,
            "derived": list(self.derived),
            "lag": self.lag,
            "calibration": {
                "mode": self.calibration,
                "fallback_objective": REJECT_ALL_OBJECTIVE + FALLBACK_MARGIN,
                "description": "rejection off where no operating point beats rejecting everything on validation"
                if self.calibration == "fallback"
                else "the operating point of the best validation objective, whatever it is",
            },
            "quick": self.quick,
            "grids": {n: REGISTRY[n].grid(self.quick) for n in self.methods if REGISTRY[n].batch is None},
            **({"enroll": self.enroll, "enrol_adaptations": list(self.enrol_adaptations)} if self.enroll else {}),
        }

    def _normalisation(self) -> dict:
        """The normalisation, or the choices the inner folds choose among (``selected.normalise`` per fold)."""
        one = len(self.normalise) == 1
        out = {"mode": self.normalise[0]} if one else {"mode": "inner folds", "choices": list(self.normalise)}
        out["description"] = "; ".join(NORMALISATION_DESCRIPTIONS[n] for n in self.normalise)
        return {**out, **(RunningStandardizer().get_params() if "recording" in self.normalise else {})}


def calibrate_background(
    data: RecordingSet,
    delay: int,
    history: int,
    derived: str = "none",
    known: list[str] | None = None,
    random_state: int = 0,
    steps: int = UKRCLMMethod.steps,
    calibration: str = CALIBRATIONS[0],
    progress: Callable[[str], None] = lambda msg: None,
) -> Choice:
    """The background factor of UKR/CLM models trained on all of ``data`` (``train-classes``,
    for the online node), chosen by the evaluation's inner folds and calibration rule with the
    models' delay window, history H, derived features and training steps: ``fallback`` is set
    (and ``reject`` is 0, no background) when no background level beats rejecting everything
    (docs/segmentation.md)."""
    method = UKRCLMMethod()
    method.steps = steps
    params = {"delay": delay, "history": history, "derived": derived, "normalise": "training"}
    return _calibrate_on_all(data, method, params, known, random_state, calibration, progress, scaled=True)


def calibrate_null_score(
    data: RecordingSet,
    kind: str,
    window: int,
    known: list[str] | None = None,
    random_state: int = 0,
    calibration: str = CALIBRATIONS[0],
    progress: Callable[[str], None] = lambda msg: None,
) -> Choice:
    """The null class's score of a ``kind`` scorer (``minirocket``, ``dtw``) fitted on all of
    ``data`` (``fit-scorer``, for the online node): the rejection threshold on the scorer's scale,
    chosen as ``clm_<kind>`` chooses it in a fold of the evaluation — its inner folds, the
    calibration rule and the gate by the scorer's own calibration — with the scorer's window on
    the raw channels the scorer is fitted on; ``fallback`` is set (and ``reject`` is −inf,
    rejection off) when rejection cannot be calibrated (docs/segmentation.md, "Score sources")."""
    params = {"window": window, "derived": "none"}
    return _calibrate_on_all(data, REGISTRY[f"clm_{kind}"], params, known, random_state, calibration, progress)


def _calibrate_on_all(
    data: RecordingSet,
    method,
    params: dict,
    known: list[str] | None,
    random_state: int,
    calibration: str,
    progress: Callable[[str], None],
    scaled: bool = False,
) -> Choice:
    """The evaluation's choice of ``method``'s rejection value with ``params`` on the inner folds of
    all of ``data`` (the models a command writes): the calibration rule, gated by the method's
    scorer (``rejects_with``) as in :meth:`RecordingsEvaluator._select`; the recordings z-scored
    with all their frames (``scaled``, the ``"training"`` normalisation) or as they are.  A
    ValueError when ``data`` cannot be calibrated (too few recordings or classes)."""
    derived = params["derived"]
    ev = RecordingsEvaluator(
        data,
        known,
        (method.name,),
        random_state=random_state,
        progress=progress,
        derived=(derived,),
        calibration=calibration,
    )
    train = ev.fold_views(None)["training", derived][0] if scaled else list(data.recordings)
    scorer = method.rejects_with
    gate = None if scorer is None else ev._calibrated(scorer, train, params)[0].objective
    return ev._rule(method.name, [ev._calibrated(method, train, params)], gate)


__getattr__ = renamed(__name__, {"StreamEvaluator": "RecordingsEvaluator"})  # the names before the recordings rename
