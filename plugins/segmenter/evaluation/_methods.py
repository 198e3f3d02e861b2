"""The method registry of both evaluation protocols (docs/segmentation.md): every recogniser by
its name, as a frame labeller for continuous recordings and, where the trajectory protocol runs
it, as a labeller of the trajectory cases (:data:`REGISTRY`).

A method is fitted on training segments per known class (global class indices),
then labels a recording in two stages: :meth:`~FrameMethod.prepare` does the expensive part once
(projection onto the class manifolds, window scores), :meth:`~FrameMethod.labels` applies one
value of the method's *rejection parameter* — a score threshold for the classifiers and the CLM
over their scores, the background strength for the UKR/CLM — optionally with one class removed from the model set (the
pseudo-unknown of the calibration).  Labels are global class indices, ``−1`` = rejected.

Each method declares the modules it needs beyond the core (``requires``, as a node does);
:func:`methods_to_run` checks them before an evaluation computes anything.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Collection, Iterable
from dataclasses import dataclass

import numpy as np

from handflow.framework.files.inputs import missing_modules

from ..base import REJECTED
from ..clm import CLMSegmenter, UKROnlyRecognizer, default_solver
from ..compatibility import (
    evidence_band,
    evidence_temperature,
    history_compatibility,
    novelty_weight,
    null_class_evidence,
    reject_segments,
    score_evidence,
)
from ..models import CandidateSet, Projection, fit_recording_models
from ..novelty import distance_weight
from ..online import OnlineCLMSegmenter
from ..scorers import MiniRocketScorer, PerClassHMM, SlidingDTW1NN, decide
from ._metrics import score_thresholds, threshold_labels
from ._selection import FULL, Fidelity

MIN_PROGRESS = (0.0, 0.3)  # the CLM's min_progress grid (periods; docs/segmentation.md)
MIN_SPANS = (0, 20)  # the CLM's min_span grid (observations; docs/segmentation.md)
MAX_FIT_RATIOS = (None, 2.0)  # the CLM's max_fit_ratio grid (None = off; docs/segmentation.md)


@dataclass
class Fitted:
    """A fitted model over the known classes ``classes`` (global indices, model column order)."""

    model: object
    classes: list[int]
    params: dict
    training: list[np.ndarray] | None = None  # training segments, kept by methods that need them after fitting


def _columns(fitted: Fitted, drop: int | None) -> list[int]:
    return [k for k, c in enumerate(fitted.classes) if c != drop]


def _to_global(local: np.ndarray, classes: list[int]) -> np.ndarray:
    lut = np.r_[np.asarray(classes, dtype=int), REJECTED]
    return lut[np.where(local < 0, len(classes), local)]


class Method:
    """One entry of the registry: what the two protocols ask of a method besides labelling.

    ``on_trajectories``: the trajectory protocol runs it (:meth:`trajectory_grid`,
    :meth:`predict_case`, given the protocol's ``Evaluator``); ``repeated_runs``: its test cases
    run ``runs`` times (a stochastic solver); ``strong_background``: it is also judged on the
    rejection experiments with a strong background; ``batch``: the method whose fitted models an
    online method replays sample by sample (None: it is fitted itself); ``rejects_with``: the
    scorer on whose scale it rejects, whose calibration also decides whether it may reject at all
    (docs/segmentation.md); ``requires``: modules beyond the core → the extra that installs them
    (as ``Node.requires``).
    """

    name = ""
    on_trajectories = False
    manifolds = False  # recognises with the class manifolds (their figures can be drawn)
    repeated_runs = False
    strong_background = False
    batch: Method | None = None
    rejects_with: Method | None = None
    requires: dict[str, str] = {}


class ThresholdOnTrajectories:
    """The trajectory protocol's classifier baselines: scores of the cases' sequences, rejection =
    a threshold on the winning score (the evaluator's data-derived grid)."""

    on_trajectories = True

    def trajectory_grid(self, evaluator, split: str) -> list[dict]:
        return [{"threshold": th} for th in evaluator.baseline_thresholds(self.name, split)]

    def predict_case(self, evaluator, params: dict, split: str, case, seed: int) -> np.ndarray:
        scores = evaluator.baseline_scores(self.name, split, case)
        keep = [k for k, c in enumerate(evaluator.classes) if c != case.left_out]
        labels = decide(scores[:, keep], params.get("threshold"))
        return evaluator.to_global(labels, [evaluator.classes[k] for k in keep])


class ScoreMethod(Method, ABC):
    """Methods with per-frame class scores; rejection = a threshold on the winning score."""

    has_features = False  # whether :meth:`prepare_with_novelty` gives a feature novelty

    @property
    def fit_key(self) -> str:
        """Methods with the same key share fitted models and prepared states (the evaluation caches them)."""
        return self.name

    @abstractmethod
    def grid(self, quick: bool) -> list[dict]:
        """Parameter sets tried on the inner validation split."""

    @abstractmethod
    def fit(self, segments: dict[int, list[np.ndarray]], params: dict, seed: int, fidelity: Fidelity = FULL) -> Fitted:
        """Fit on training segments per known class (global class indices); ``fidelity``: what
        the fit may spend (:mod:`._selection`; only the class manifolds have a cheaper form)."""

    @abstractmethod
    def prepare(self, fitted: Fitted, X: np.ndarray) -> np.ndarray:
        """Per-frame state of a recording (class scores), from which :meth:`labels` decides."""

    def prepare_with_novelty(self, fitted: Fitted, X: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`prepare` and the frames' feature novelty (:mod:`..novelty`; None without features)."""
        return self.prepare(fitted, X), None

    def labels(self, fitted: Fitted, state: np.ndarray, reject: float, drop: int | None = None) -> np.ndarray:
        cols = _columns(fitted, drop)
        return _to_global(threshold_labels(state[:, cols], reject), [fitted.classes[k] for k in cols])

    def temperature(self, fitted: Fitted) -> float:
        """The evidence temperature the online node maps this scorer's scores with: that of its
        training frames' scores, fixed at fitting (:class:`..scorers.WindowScorer`)."""
        return fitted.model.temperature_

    def reject_grid(self, fitted: Fitted, states: list[np.ndarray], n: int = 41) -> np.ndarray:
        """Thresholds at ``n`` quantiles of the winning score (:func:`._metrics.score_thresholds`)."""
        return score_thresholds(np.concatenate([s.max(axis=1) for s in states]), n)

    def without_class(self, fitted: Fitted, segments: dict[int, list[np.ndarray]], drop: int, seed: int):
        """A model that never saw class ``drop`` (the calibration's pseudo-unknown), or None when
        ``labels(..., drop=drop)`` already is one: per-class models (DTW references, HMMs) just
        leave that class's model out."""
        return None


class DTWMethod(ThresholdOnTrajectories, ScoreMethod):
    """Sliding-window subsequence DTW 1-NN (:class:`SlidingDTW1NN`); parameter: the window."""

    name = "dtw_1nn"

    def grid(self, quick: bool) -> list[dict]:
        return [{"window": w} for w in ((20,) if quick else (10, 30))]

    def fit(self, segments, params, seed, fidelity=FULL) -> Fitted:
        classes = sorted(segments)
        model = SlidingDTW1NN(window=params["window"]).fit({c: _thin(segments[c], 4) for c in classes})
        return Fitted(model, classes, params, training=[s for c in classes for s in segments[c]])

    def prepare(self, fitted, X):
        return fitted.model.scores(X)

    def temperature(self, fitted: Fitted) -> float:
        """:class:`..scorers.DTWScorer`'s: that of the training frames' scores against the thinned
        references, computed when first asked (``clm_dtw``; scoring them costs ``dtw_1nn`` nothing)."""
        model = fitted.model
        if not hasattr(model, "temperature_"):
            model.temperature_ = evidence_temperature(np.vstack([model.scores(s) for s in fitted.training]))
        return model.temperature_

    @staticmethod
    def trajectory_model(evaluator) -> SlidingDTW1NN:
        return evaluator.dtw


class HMMMethod(ThresholdOnTrajectories, ScoreMethod):
    """Per-class Gaussian HMMs, windowed log-likelihood (:class:`PerClassHMM`); states and window."""

    name = "hmm"
    requires = PerClassHMM.requires

    def grid(self, quick: bool) -> list[dict]:
        return [{"n_states": s, "window": w} for s in ((4,) if quick else (3, 6)) for w in (20,)]

    def fit(self, segments, params, seed, fidelity=FULL) -> Fitted:
        classes = sorted(segments)
        model = PerClassHMM(n_states=params["n_states"], window=params["window"], random_state=seed)
        return Fitted(model.fit({c: segments[c] for c in classes}), classes, params)

    def prepare(self, fitted, X):
        return fitted.model.scores(X)

    @staticmethod
    def trajectory_model(evaluator) -> PerClassHMM:
        return evaluator.hmm


class MiniRocketMethod(ScoreMethod):
    """MiniRocket features of the causal window ending at each frame + a ridge classifier
    (:class:`..scorers.MiniRocketScorer`, aeon).  The calibration's pseudo-unknowns are models
    refitted without the class (:meth:`without_class`)."""

    name = "minirocket"
    requires = MiniRocketScorer.requires

    def __init__(self, feature_novelty: bool = False) -> None:
        self.has_features = feature_novelty  # fit the scorer's feature novelty (only the novelty method uses it)

    def grid(self, quick: bool) -> list[dict]:
        return [{"window": w} for w in ((32,) if quick else (16, 48))]

    def fit(self, segments, params, seed, fidelity=FULL) -> Fitted:
        scorer = MiniRocketScorer(window=params["window"], random_state=seed, feature_novelty=self.has_features)
        scorer.fit(dict(sorted(segments.items())))
        return Fitted(scorer, list(scorer.classes_), params)

    def prepare(self, fitted, X):
        return fitted.model.scores(X)

    def prepare_with_novelty(self, fitted, X):
        return fitted.model.scores_and_novelty(X)

    def without_class(self, fitted, segments, drop, seed):
        """Refitted without ``drop``: the ridge is fitted on all classes at once, so with a class's
        column merely dropped the other columns would still have learnt to be low on its frames —
        a pseudo-unknown far easier to reject than a class never seen (docs/segmentation.md).
        None with two known classes: a ridge needs two, so the column is dropped then."""
        rest = {c: s for c, s in segments.items() if c != drop}
        return self.fit(rest, fitted.params, seed) if len(rest) >= 2 else None


def _thin(seqs: list[np.ndarray], k: int) -> list[np.ndarray]:
    """Every k-th frame of long references (documented choice: keeps DTW affordable; ≥ 8 frames)."""
    return [s[::k] if len(s) >= 8 * k else s for s in seqs]


class UKRMethod(Method):
    """Shared part of the manifold methods: one periodic structured UKR per class over a delay
    embedding of the frames, errors in one metric (:func:`..models.fit_recording_models`); the
    delay window is chosen on validation.  On trajectories the class models are the protocol's
    candidates (without the left-out class of a case)."""

    on_trajectories = True
    manifolds = True
    steps = 150
    delays = ((8,), (4, 8, 16))  # delay windows (frames, step 1) of the quick and the full grid

    @property
    def fit_key(self) -> str:
        return "ukr"

    def _fit_candidates(self, segments, seed, delay: int, fidelity: Fidelity = FULL) -> CandidateSet:
        by_class = {str(c): segments[c] for c in sorted(segments)}
        budget = {
            k: v
            for k, v in (("max_points", fidelity.max_points), ("statistics_frames", fidelity.statistics_frames))
            if v is not None
        }
        steps = self.steps if fidelity.steps is None else fidelity.steps
        return fit_recording_models(by_class, delay=delay, n_steps=steps, random_state=seed, **budget)

    def prepare(self, fitted: Fitted, X: np.ndarray) -> Projection:
        return fitted.model.project(X)

    def without_class(self, fitted, segments, drop, seed):
        """None: one manifold per class, so leaving class ``drop``'s out is a model without it."""
        return None

    @staticmethod
    def _view(fitted: Fitted, proj: Projection, drop: int | None) -> tuple[CandidateSet, Projection, list[int]]:
        if drop is None or drop not in fitted.classes:
            return fitted.model, proj, fitted.classes
        return fitted.model.without(str(drop)), proj.without(str(drop)), [c for c in fitted.classes if c != drop]


class UKRCLMMethod(UKRMethod):
    """The UKR/CLM segmenter over the whole recording with ``reconstruction="relative"``
    (:class:`CLMSegmenter`); rejection = the background factor (the null model's error is
    1 / factor in units of the training frames' median error)."""

    name = "ukr_clm"
    repeated_runs = True
    strong_background = True
    histories = ((20,), (10, 20))  # CLM neighbourhood H of the quick and the full grid
    label_params = ("history",)  # chosen without refitting the class models

    def grid(self, quick: bool) -> list[dict]:
        return [{"delay": w, "history": h} for w in self.delays[not quick] for h in self.histories[not quick]]

    def trajectory_grid(self, evaluator, split: str) -> list[dict]:
        """In the order of preference a tie keeps (docs/segmentation.md, "How the trajectory
        protocol chooses"): the spec's background ×1 and error scale 1 first; for the segment
        rules and the neighbourhood the documented choices (``min_progress`` 0.3,
        ``max_fit_ratio`` 2, ``min_span`` 20) before the spec's plain CLM, which has to beat
        them by more than the noise."""
        return [
            {"background_factor": f, "error_scale": e, "min_progress": p, "min_span": s, "max_fit_ratio": r}
            for e in (1.0, 0.1)
            for f in (1.0, 0.5, 0.25, 0.1, 1.5, 2.0, 3.0)
            for p in MIN_PROGRESS[::-1]
            for s in MIN_SPANS[::-1]
            for r in MAX_FIT_RATIOS[::-1]
        ]

    def predict_case(self, evaluator, params: dict, split: str, case, seed: int) -> np.ndarray:
        proj, cands = evaluator.projection(split, case), evaluator.case_candidates(case)
        labels = reject_segments(
            evaluator.clm_labels(split, case, seed, cands, proj, params),
            proj.latent_time,
            proj.errors,
            params.get("min_progress", 0.0),
            params.get("max_fit_ratio"),
            reversed_errors=proj.reversed_errors,
        )
        return evaluator.to_global(labels, proj.classes)

    def fit(self, segments, params, seed, fidelity=FULL) -> Fitted:
        return Fitted(self._fit_candidates(segments, seed, params["delay"], fidelity), sorted(segments), params)

    def segmenter(self, candidates: CandidateSet, reject: float, history: int, kind=CLMSegmenter) -> CLMSegmenter:
        """The batch segmenter of this method, or (``kind=OnlineCLMSegmenter``) the online one with the same settings."""
        return kind(
            candidates,
            history=history,
            background_factor=reject,
            reconstruction="relative",
            solver=default_solver(candidates, max_sweeps=300, spectral=kind.SPECTRAL),
            random_state=0,
        )

    def labels(self, fitted, state, reject, drop=None):
        cands, proj, classes = self._view(fitted, state, drop)
        return _to_global(self.segmenter(cands, reject, fitted.params["history"]).fit_predict_projected(proj), classes)

    def reject_grid(self, fitted, states) -> np.ndarray:
        return np.array([0.0, 1 / 32, 1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0, 2.0, 4.0, 8.0, 16.0, 64.0])


class UKROnlyMethod(UKRMethod):
    """Winner-take-all over the UKR compatibilities; rejection = a threshold on the winning C."""

    name = "ukr_only"
    label_params = ("lam", "order_rating")  # chosen without refitting the class models

    def grid(self, quick: bool) -> list[dict]:
        lams = (0.5,) if quick else (0.3, 0.5)
        return [{"lam": lam, "order_rating": "cos", "delay": w} for lam in lams for w in self.delays[not quick]]

    def trajectory_grid(self, evaluator, split: str) -> list[dict]:
        return [
            {"lam": lam, "gamma": 0.9, "order_rating": r, "threshold": th}
            for th in (None, 0.5, 0.0)
            for r in ("cos", "sign")
            for lam in (0.3, 0.5)
        ]

    def predict_case(self, evaluator, params: dict, split: str, case, seed: int) -> np.ndarray:
        proj, cands = evaluator.projection(split, case), evaluator.case_candidates(case)
        labels = UKROnlyRecognizer(cands, history=case.history, **params).predict_projected(proj)
        return evaluator.to_global(labels, proj.classes)

    def fit(self, segments, params, seed, fidelity=FULL) -> Fitted:
        return Fitted(self._fit_candidates(segments, seed, params["delay"], fidelity), sorted(segments), params)

    def _compat(self, fitted, proj, cands) -> np.ndarray:
        rec = UKROnlyRecognizer(cands, lam=fitted.params["lam"], order_rating=fitted.params["order_rating"])
        return rec.compatibilities_projected(proj)

    def labels(self, fitted, state, reject, drop=None):
        cands, proj, classes = self._view(fitted, state, drop)
        return _to_global(threshold_labels(self._compat(fitted, proj, cands), reject), classes)

    def reject_grid(self, fitted, states) -> np.ndarray:
        return score_thresholds(np.concatenate([self._compat(fitted, s, fitted.model).max(axis=1) for s in states]))


class ScoreCLMMethod(Method):
    """The CLM as a segmentation layer over a classifier's per-frame scores: evidence
    (:func:`..compatibility.score_evidence` at the scorer's temperature fixed at fitting, as the
    online node maps them) → banded compatibilities within the history H
    (:func:`..compatibility.evidence_band`) → one CLM layer per class plus the background, the
    layer of a null class; rejection = the null class's score, a threshold on the scorer's scale
    swept at the scorer's deciles and calibrated like every method's, and off wherever the
    scorer's is (``rejects_with``; docs/segmentation.md)."""

    history = 10
    thresholds = 11  # quantiles of the null class's score sweep (documented choice: each costs CLM runs)
    run_length = 2048  # longer recordings are solved in overlapping runs (documented choice: linear cost)

    def __init__(self, scorer: ScoreMethod) -> None:
        self.scorer = scorer
        self.rejects_with = scorer
        self.name = f"clm_{scorer.name.removesuffix('_1nn')}"
        self.requires = scorer.requires

    def grid(self, quick: bool) -> list[dict]:
        return self.scorer.grid(quick)

    def fit(self, segments, params, seed, fidelity=FULL) -> Fitted:
        return self.scorer.fit(segments, params, seed)

    @property
    def fit_key(self) -> str:
        return self.scorer.fit_key

    def prepare(self, fitted, X) -> np.ndarray:
        return self.scorer.prepare(fitted, X)

    def without_class(self, fitted, segments, drop, seed):
        return self.scorer.without_class(fitted, segments, drop, seed)

    def _temperature(self, fitted: Fitted) -> float:
        """The scorer's evidence temperature, fixed at fitting as the online node's
        (:meth:`ScoreMethod.temperature`)."""
        return self.scorer.temperature(fitted)

    def evidence(self, fitted: Fitted, state, drop: int | None) -> np.ndarray:
        """Per-frame evidence (N, M) of the classes left after ``drop``, rows summing to 1."""
        evidence = score_evidence(state, self._temperature(fitted))[:, _columns(fitted, drop)]
        return evidence / evidence.sum(axis=1, keepdims=True)

    def labels(self, fitted, state, reject, drop=None):
        """The CLM over the classes' evidence and a null class scoring ``reject`` on the scorer's
        scale (:func:`..compatibility.null_class_evidence`), the background being its layer."""
        cols = _columns(fitted, drop)
        evidence = null_class_evidence(state[:, cols], reject, self._temperature(fitted))
        return self._segmented(evidence, [fitted.classes[k] for k in cols], "relative", reject)

    def _segmented(self, evidence: np.ndarray, classes: list[int], reconstruction: str, factor: float) -> np.ndarray:
        """The CLM's labels (global) of ``evidence`` within H: with ``"relative"`` its last column
        is the background's, with ``"absolute"`` the thesis background of ``factor`` is added."""
        seg = CLMSegmenter(
            None,
            history=self.history,
            background_factor=factor,
            reconstruction=reconstruction,
            solver=default_solver(max_sweeps=300),
            run_length=self.run_length,
            random_state=0,
        )
        _, _, width = seg.widths()
        local = seg.fit_predict_bands(*seg.with_background(evidence_band(evidence, width, self.history)))
        return _to_global(local, classes)

    def reject_grid(self, fitted, states) -> np.ndarray:
        """The scorer's own threshold sweep at ``thresholds`` quantiles: the null class's score is
        calibrated by the scorer's rule."""
        return self.scorer.reject_grid(fitted, states, self.thresholds)


class NoveltyCLMMethod(ScoreCLMMethod):
    """:class:`ScoreCLMMethod` with a novelty term from the class manifolds: a frame whose best
    manifold's error exceeds ``1 / novelty`` times that manifold's own typical error on its
    training frames has its classifier evidence scaled down by the ratio,
    ``w = min(1, own / (novelty · error))``; and class m's evidence where the frame's motion
    intensity lies outside m's training range (:mod:`..novelty`, weight ``i_m``):
    ``e_m = p_m · mean(w · i_m · f)``, the mean over the frame and the H − 1 before it (the γ = 1
    history average), before the banding of :func:`..compatibility.evidence_band`; ``f`` is the
    weight of the frame's feature novelty for scorers with features
    (:func:`..novelty.distance_weight` beyond the z-score ``distance_z``, 1 when it is None).  A frame that no
    class model explains falls below chance in every class layer and goes to the background,
    however confident the classifier is;
    ``novelty`` and ``distance_z`` are chosen on validation without refitting.  Rejection = the thesis background's
    factor (the novelty weights, not the scores, decide what falls below chance); a pseudo-unknown of the calibration has the scorer refitted
    without its class (:meth:`without_class`) and its manifold left out (docs/segmentation.md)."""

    ukr = UKRMethod()
    delays = ((8,), (8, 16))  # delay windows of the manifolds in the quick and the full grid
    novelties = ((0.125, 0.25), (0.125, 0.25, 0.5))  # of the quick and the full grid
    distance_zs = (1.0, 2.0)  # feature-novelty limits of scorers with features (docs/segmentation.md)
    label_params = ("novelty", "distance_z")

    def __init__(self, scorer: ScoreMethod) -> None:
        super().__init__(scorer)
        self.name = f"{self.name}_novelty"
        self.rejects_with = None  # its novelty weights reject, beyond what the scores separate

    def grid(self, quick: bool) -> list[dict]:
        return [
            {**p, "delay": w, "novelty": v, "distance_z": z}
            for p in self.scorer.grid(quick)
            for w in self.delays[not quick]
            for v in self.novelties[not quick]
            for z in (self.distance_zs if self.scorer.has_features else (None,))
        ]

    def fit(self, segments, params, seed, fidelity=FULL) -> Fitted:
        scorer = self.scorer.fit(segments, params, seed, fidelity)
        manifolds = self.ukr._fit_candidates(segments, seed, params["delay"], fidelity)
        return Fitted((scorer, manifolds), scorer.classes, params)

    @property
    def fit_key(self) -> str:
        return self.name

    def prepare(self, fitted, X):
        scorer, manifolds = fitted.model
        scores, novelty = self.scorer.prepare_with_novelty(scorer, X)
        return scores, novelty, manifolds.project(X), manifolds.intensity_weights(X)

    def without_class(self, fitted, segments, drop, seed):
        """The scorer refitted without ``drop`` if it needs it; the manifolds leave its one out."""
        scorer, manifolds = fitted.model
        refit = self.scorer.without_class(scorer, segments, drop, seed)
        if refit is None:
            return None
        return Fitted((refit, manifolds.without(str(drop))), refit.classes, fitted.params)

    def _temperature(self, fitted: Fitted) -> float:
        return self.scorer.temperature(fitted.model[0])

    def evidence(self, fitted: Fitted, state, drop: int | None) -> np.ndarray:
        scores, novelty, proj, intensity = state
        kept = [j for j, c in enumerate(proj.classes) if drop is None or c != str(drop)]
        cands, proj, _ = UKRMethod._view(Fitted(fitted.model[1], fitted.classes, fitted.params), proj, drop)
        known = novelty_weight(proj.errors, cands.own_errors, fitted.params["novelty"], intensity[:, kept])
        if novelty is not None:
            known = known * distance_weight(novelty, fitted.params["distance_z"])[:, None]
        return super().evidence(fitted, scores, drop) * history_compatibility(known, self.history, 1.0)

    def labels(self, fitted, state, reject, drop=None):
        """The CLM over the novelty-weighted evidence with the thesis background of factor ``reject``."""
        evidence = self.evidence(fitted, state, drop)
        return self._segmented(evidence, [fitted.classes[k] for k in _columns(fitted, drop)], "absolute", reject)

    def reject_grid(self, fitted, states) -> np.ndarray:
        """Background factors: the novelty weights, not the scores, decide what falls below chance."""
        return np.array([0.0, 0.05, 0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0])


class UKRCLMOnlineMethod(Method):
    """The UKR/CLM segmenter run online (:class:`..online.OnlineCLMSegmenter`) with the models and
    the rejection chosen for :class:`UKRCLMMethod` (``batch``): each frame's final published label,
    on arrival, then confirmed revisions."""

    name = "ukr_clm_online"

    def __init__(self, batch: UKRCLMMethod) -> None:
        self.batch = batch
        self.requires = batch.requires

    def labels_online(self, fitted: Fitted, reject: float, X: np.ndarray) -> np.ndarray:
        seg = self.batch.segmenter(fitted.model, reject, fitted.params["history"], kind=OnlineCLMSegmenter)
        published = np.full(len(X), -1)
        for y in X:
            update = seg.push(y)
            published[update.index] = update.label
            for ev in update.events:
                if ev.kind == "revision":
                    published[ev.start : ev.end + 1] = ev.label
        for ev in seg.finish():  # the recording ends: the last observations get their final labels
            if ev.kind == "revision":
                published[ev.start : ev.end + 1] = ev.label
        lut = np.r_[np.asarray(fitted.classes), -1]
        return lut[np.where(published < 0, len(fitted.classes), published)]


_UKR_CLM = UKRCLMMethod()
REGISTRY: dict[str, Method] = {
    m.name: m
    for m in (
        UKROnlyMethod(),
        _UKR_CLM,
        DTWMethod(),
        HMMMethod(),
        UKRCLMOnlineMethod(_UKR_CLM),
        MiniRocketMethod(),
        ScoreCLMMethod(MiniRocketMethod()),
        ScoreCLMMethod(DTWMethod()),
        NoveltyCLMMethod(MiniRocketMethod(feature_novelty=True)),
        NoveltyCLMMethod(DTWMethod()),
    )
}
METHODS = REGISTRY  # the name of the flat layout
TRAJECTORY_METHODS = tuple(name for name, m in REGISTRY.items() if m.on_trajectories)


def missing_extras(names: Iterable[str]) -> dict[str, str]:
    """Method → what to install, for the registry methods of ``names`` whose extra is missing."""
    return {name: "; ".join(why) for name in names if (why := missing_modules(REGISTRY[name].requires))}


def methods_to_run(
    option: str | None, default: tuple[str, ...], allowed: Collection[str], progress: Callable[[str], None]
) -> tuple[tuple[str, ...], dict[str, str]]:
    """The methods an evaluation runs and those it skips (method → what to install), before it
    computes anything (docs/segmentation.md, "Methods and their extras"): the comma-separated
    ``option`` (``--methods``) as given — a ValueError when a name is unknown or its extra is
    missing — or, without it, those of ``default`` whose extras are installed."""
    if not option:
        skipped = missing_extras(default)
        for name, why in skipped.items():
            progress(f"skipping {name}: it {why}")
        return tuple(m for m in default if m not in skipped), skipped
    names = tuple(m for m in option.split(",") if m)
    unknown = sorted(set(names) - set(allowed))
    if unknown:
        raise ValueError(f"unknown method(s) {unknown}; choose from {list(allowed)}")
    missing = missing_extras(names)
    if missing:
        raise ValueError(
            "; ".join(f"method {name} {why}" for name, why in missing.items()) + " (or leave it out of --methods)"
        )
    return names, {}
