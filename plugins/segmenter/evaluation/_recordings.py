"""Leave-one-recording-out evaluation on continuous recordings (docs/segmentation.md).

A fold, top-down (:meth:`RecordingsEvaluator.run_fold`): the held-out recording is left out and
the others train.  Every recording gets each choice of derived features (``derived``,
:mod:`..features`) and is scaled with the fold's training frames (``normalise``: z-scored with
their statistics, ``"training"``, or each recording causally with its own running ones and those
as the prior, ``"recording"``) — one *view* per choice (:meth:`~RecordingsEvaluator.fold_views`).
Per method, its view, grid point and rejection value are chosen by successive halving on inner
splits of the training recordings (:mod:`._selection`, calibrated by :mod:`._calibration`: the
mean of the known accuracy and the rejection of pseudo-unknowns, and the fallback rule).  The
chosen candidate is fitted at full fidelity on all training recordings (:mod:`._fidelity`) and
labels the held-out recording frame by frame; with ``enroll`` it is fitted once more with the
recording's first segments (:mod:`._enrolment`).  ``ukr_clm_online`` replays ``ukr_clm``'s models
sample by sample through :class:`OnlineCLMSegmenter` (its ``agreement``: the share of frames equal
to the batch labels).  Frames of labels outside ``known`` are never used for training or
calibration.

The folds run one after the other or over ``jobs`` processes (:mod:`._folds`, with ``checkpoints``);
the figures, pooled over the folds' frames, are computed by :mod:`._report`.  ``lag`` labels each
frame from the evidence of the window ending ``lag`` frames later (:func:`..base.lagged`), in the
calibration as in the figures.  :func:`calibrate_background` and :func:`calibrate_null_score`
apply the calibration to the models ``train-classes`` and the scorers ``fit-scorer`` write for
the online node.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable

import numpy as np

from .._moved import renamed
from ..base import lagged
from ..datasets import ADAPTATIONS, Recording, RecordingSet, enrolment_split
from ..features import DERIVED, ChannelScaling, RunningStandardizer, derive
from ._calibration import (
    CALIBRATIONS,
    FALLBACK_MARGIN,
    INNER_FOLDS,
    MIN_TRAINED_CLASSES,  # noqa: F401  (a name of the old path stream_evaluation)
    PSEUDO_UNKNOWNS,
    REJECT_ALL_OBJECTIVE,
    Choice,
    InnerFoldCalibration,
    inner_folds,
)
from ._chosen import ChosenParameters
from ._enrolment import (
    CHOSEN,
    EVALUATION_ADAPTATIONS,
    EnrolmentFits,
    check_enrolment,
    enrolled_views,
)
from ._fidelity import NESTED, PREVIEW
from ._fold_result import FoldResult, MethodFold, timing
from ._folds import FoldRunner
from ._methods import REGISTRY, UKRCLMMethod
from ._preview import PreviewRunner
from ._protocols import protocol
from ._report import Report, choice_summary
from ._selection import HalvingSelection

DEFAULT_METHODS = ("ukr_clm", "ukr_clm_online", "ukr_only", "dtw_1nn", "hmm", "minirocket", "clm_minirocket")


NORMALISATIONS = ("training", "recording")


NORMALISATION_DESCRIPTIONS = {
    "training": "z-score with the fold's training frames (every method)",
    "recording": "each recording standardised causally, prior = the fold's training frames (every method)",
}


def _zscore(train: list[Recording], recs: list[Recording], normalise: str = "training") -> list[Recording]:
    """``recs`` z-scored with the mean and standard deviation of the frames of ``train``
    (``"training"``) or causally with running ones, each recording on its own, those frames being
    the prior (``"recording"``, :class:`..features.RunningStandardizer`)."""
    if normalise == "training":
        scaler = ChannelScaling().fit([r.X for r in train])
    else:
        scaler = RunningStandardizer().fit(np.vstack([r.X for r in train]))
    return [Recording(r.name, scaler.transform(r.X), r.y) for r in recs]


class RecordingsEvaluator(HalvingSelection, InnerFoldCalibration, EnrolmentFits, FoldRunner, PreviewRunner, Report):
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
        chosen: ChosenParameters | None = None,
        cache: str | None = None,
        scheduler: str | None = None,
        preview: bool = False,
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
        if preview and (enroll or checkpoints or chosen or cache or scheduler):
            raise ValueError(
                "--preview takes no --enroll, --checkpoints, --cache, --params or --scheduler: they belong to the "
                "nested protocol (drop them or --preview)"
            )
        self.preview = preview  # the preview protocol (:mod:`._preview`) instead of the nested one
        self.halving = PREVIEW if preview else NESTED  # its successive halving (:mod:`._fidelity`)
        self._threads = None  # the preview's threads that label a calibration's folds
        self.data = data
        known = known or data.known_classes  # a dataset's unknown_classes (rest) are unknown by default
        self.known = [data.class_names.index(k) for k in known]
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
        self.chosen = chosen  # parameters of an earlier run: no selection (``--params``)
        self.cache = cache  # a directory of every method's finished parts of folds (``--cache``)
        self._stores: dict = {}  # method → its store in ``cache``
        self.scheduler = scheduler  # a dask scheduler's address: the folds run on its cluster
        if chosen is not None:
            chosen.check(tuple(m for m in methods if REGISTRY[m].batch is None), self.normalise, self.derived)
        self._cache: dict[tuple, object] = {}
        self._fold_choices: dict[str, list] = {}  # method → its calibrated parameter sets in this fold
        self._timing: dict[str, dict[str, float]] = {}  # method → phase → seconds, in this fold

    def __getstate__(self) -> dict:
        """What travels to a worker process: the evaluator without this process's fold cache
        (a worker starts its own)."""
        return {**self.__dict__, "_cache": {}, "_fold_choices": {}, "_threads": None}

    def fold_views(self, held: str | None) -> dict[tuple[str, str], tuple[list[Recording], Recording | None]]:
        """Per (normalisation, derived features) choice: the training recordings and the held-out one
        (None: all recordings train), with the features appended and then scaled with the training
        frames.  Starts the fold: fitted models and states of the previous one are dropped."""
        self._cache.clear()
        return self.views(held)

    def views(self, held: str | None) -> dict[tuple[str, str], tuple[list[Recording], Recording | None]]:
        """:meth:`fold_views` without starting a fold (the preview keeps every fold's fits)."""
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
        """The fold that holds out ``held``: every method chosen, fitted and labelling it."""
        views = self.fold_views(held)
        untrained = self._untrained(self.data.without(held))
        if untrained:
            self.progress(
                f"  {held}: no training segment of {untrained} in the other recordings; models leave them out"
            )
        self._fold_choices, self._timing = {}, {}
        sessions = {a: enrolled_views(views, self.known, self.enroll, a) for a in ADAPTATIONS if self.enroll}
        parts = [
            self._cached_method_fold(held, name, lambda name=name: self._method_fold(held, name, views, sessions))
            for name in self.methods
            if REGISTRY[name].batch is None  # online methods replay the models of their batch method
        ]
        return self._fold_result(held, next(iter(views.values()))[1].y, parts, untrained)

    def _fold_result(self, held: str, truth: np.ndarray, parts: list[MethodFold], untrained: list[str]) -> FoldResult:
        """The fold of ``held`` from its methods' parts."""
        return FoldResult(
            held,
            truth,
            labels={m: lagged(x, self.lag) for p in parts for m, x in p.labels.items()},
            selected={m: x for p in parts for m, x in p.selected.items()},
            sweeps={p.method: p.sweeps for p in parts},
            strict={p.method: p.strict for p in parts if p.strict is not None},
            untrained=untrained,
            unlagged={m: x for p in parts for m, x in p.labels.items()},
            enrolled={a: {m: x for p in parts for m, x in p.enrolled[a].items()} for a in self.enrol_adaptations}
            if self.enroll
            else {},
            scored_from=enrolment_split(truth, self.known, self.enroll)[1] if self.enroll else 0,
            timing={m: x for p in parts for m, x in p.timing.items()},
            warnings=dict(sum((Counter(p.warnings) for p in parts), Counter())),
        )

    def _method_fold(self, held: str, name: str, views, sessions) -> MethodFold:
        """Batch method ``name`` (with the online methods that replay its models) in the fold of
        ``held``: its choice — selected on the inner folds, or ``chosen`` — its labels of the
        held-out recording at the chosen rejection value and over its sweep, and with enrolment."""
        method, t0 = REGISTRY[name], time.perf_counter()
        with self._timed(name, "selection"):
            choice = (
                self._select(name, {key: inner_folds(train) for key, (train, _) in views.items()})
                if self.chosen is None
                else self.chosen.choice(name, held)
            )
        fitted, state, test = self._final(method, choice.params, views)
        with self._timed(name, "labelling"):
            labels = {name: method.labels(fitted, state, choice.reject)}
            sweeps = [lagged(method.labels(fitted, state, r), self.lag) for r in method.reject_grid(fitted, [state])]
        selected = choice.selected()
        strict = None
        if choice.fallback:
            strict_fit, strict_state, _ = self._final(method, choice.strict.params, views)
            with self._timed(name, "labelling"):
                strict = lagged(method.labels(strict_fit, strict_state, choice.strict.reject), self.lag)
        if self.enroll and CHOSEN in self.enrol_adaptations:
            earlier = self.chosen.selected(name, held) if self.chosen else {}
            if "enrol_adaptation" in earlier:
                selected.update({k: earlier[k] for k in ("enrol_adaptation", "enrol_validation")})
            else:
                with self._timed(name, "selection"):
                    selected["enrol_adaptation"], selected["enrol_validation"] = self._adaptation(method, choice, views)
        self.progress(f"  {held}: {name} {choice_summary(selected)} in {time.perf_counter() - t0:.1f} s")
        self.detail(f"    {name}: {selected}")
        labels.update(self._replayed(method, fitted, choice.reject, test))
        enrolled = {}
        for adaptation in self.enrol_adaptations if self.enroll else ():
            chosen = selected["enrol_adaptation"] if adaptation == CHOSEN else adaptation
            enrolled[adaptation] = (
                {m: lagged(x, self.lag) for m, x in labels.items()}
                if chosen == "none"
                else self._enrolled(method, choice, sessions[chosen])
            )
        timing = {m: self._timing.get(m, {}) for m in labels}
        return MethodFold(held, name, labels, dict.fromkeys(labels, selected), sweeps, strict, enrolled, timing)

    def _replayed(self, method, fitted, reject: float, test: Recording) -> dict[str, np.ndarray]:
        """The labels of ``test`` by the online methods that replay ``method``'s ``fitted`` models."""
        labels = {}
        for online in map(REGISTRY.get, self._replaying(method)):
            t0 = time.perf_counter()
            with self._timed(online.name, "labelling"):
                labels[online.name] = online.labels_online(fitted, reject, test.X)
            self.progress(
                f"  {test.name}: {online.name} replayed {method.name}'s models in {time.perf_counter() - t0:.1f} s"
            )
        return labels

    def _final(self, method, params: dict, views) -> tuple:
        """``method`` fitted with ``params`` on all training recordings, its state on the held-out
        recording and that recording as the method sees it (with ``params``' normalisation and
        derived features)."""
        train, test = views[params["normalise"], params["derived"]]
        with self._timed(method.name, "final_fit"):
            fitted = self._fit(method, train, params)
        with self._timed(method.name, "labelling"):
            return fitted, self._prepare(method, fitted, test), test

    def _replaying(self, method) -> list[str]:
        """The online methods of this evaluation that replay ``method``'s models."""
        return [m for m in self.methods if REGISTRY[m].batch is method]

    def evaluate(self) -> dict:
        """The result (docs/segmentation.md, JSON): the nested protocol's, or the preview's."""
        folds, spent = self._preview_folds() if self.preview else (self._run_folds(), None)
        truth = np.concatenate([f.truth for f in folds])
        out: dict = {"protocol": protocol(self.preview, "recordings"), "methods": {}, "parameters": self._parameters()}
        for name in self.methods:
            out["methods"][name] = self._method_result(folds, name, truth)
        out["timing"] = spent or timing(folds)
        out["warnings"] = self._warnings(folds)
        self.folds_ = folds
        return out

    def _parameters(self) -> dict:
        return {
            "protocol": "leave-one-recording-out; "
            + (
                "every candidate scored on these folds themselves, one choice per method for all folds (preview)"
                if self.preview
                else f"inner folds hold out each of the last {INNER_FOLDS} training recordings"
            ),
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
            **({"params_from": self.chosen.source} if self.chosen else {}),
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
    gate = None if scorer is None else ev._calibrated(scorer, inner_folds(train), params)[0].objective
    return ev._rule(method.name, [ev._calibrated(method, inner_folds(train), params)], gate)


__getattr__ = renamed(__name__, {"StreamEvaluator": "RecordingsEvaluator"})  # the names before the recordings rename
