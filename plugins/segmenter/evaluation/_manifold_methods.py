"""The manifold methods of the evaluation (docs/segmentation.md, "Methods"): one periodic
structured UKR per class, labelled by the UKR/CLM segmenter (batch and online) or by the
winning compatibility (UKR-only)."""

from __future__ import annotations

import numpy as np

from ..clm import CLMSegmenter, UKROnlyRecognizer, default_solver
from ..compatibility import reject_segments
from ..models import CandidateSet, Projection, fit_recording_models
from ..online import OnlineCLMSegmenter
from ._fidelity import FULL, Fidelity
from ._method_base import Fitted, Method, _to_global
from ._metrics import score_thresholds, threshold_labels

MIN_PROGRESS = (0.0, 0.3)  # the CLM's min_progress grid (periods; docs/segmentation.md)
MIN_SPANS = (0, 20)  # the CLM's min_span grid (observations; docs/segmentation.md)
MAX_FIT_RATIOS = (None, 2.0)  # the CLM's max_fit_ratio grid (None = off; docs/segmentation.md)


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
