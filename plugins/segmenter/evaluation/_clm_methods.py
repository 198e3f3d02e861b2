"""The CLM as a segmentation layer over a classifier's per-frame scores, with and without the
novelty terms of the class manifolds (docs/segmentation.md, "Score sources")."""

from __future__ import annotations

import numpy as np

from ..clm import CLMSegmenter, default_solver
from ..compatibility import (
    evidence_band,
    history_compatibility,
    novelty_weight,
    null_class_evidence,
    score_evidence,
)
from ..novelty import distance_weight
from ._fidelity import FULL
from ._manifold_methods import UKRMethod
from ._method_base import Fitted, Method, ScoreMethod, _columns, _to_global


class ScoreCLMMethod(Method):
    """The CLM as a segmentation layer over a classifier's per-frame scores: evidence
    (:func:`..compatibility.score_evidence` at the scorer's temperature fixed at fitting, as the
    online node maps them) → banded compatibilities within the history H
    (:func:`..compatibility.evidence_band`) → one CLM layer per class plus the background, the
    layer of a null class; rejection = the null class's score, a threshold on the scorer's scale
    swept at the scorer's deciles and calibrated like every method's, and off wherever the
    scorer's is (``rejects_with``; docs/segmentation.md)."""

    cheaper_fits = False  # its scorer's fit
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

    cheaper_fits = True  # the manifolds beside the scorer
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
