"""The classifier baselines of the evaluation (docs/segmentation.md, "Methods"): sliding DTW
1-NN, per-class HMMs and MiniRocket, each with per-frame class scores."""

from __future__ import annotations

import numpy as np

from ..compatibility import evidence_temperature
from ..scorers import MiniRocketScorer, PerClassHMM, SlidingDTW1NN, dtw_references
from ._fidelity import FULL
from ._method_base import Fitted, ScoreMethod, ThresholdOnTrajectories


class DTWMethod(ThresholdOnTrajectories, ScoreMethod):
    """Sliding-window subsequence DTW 1-NN (:class:`SlidingDTW1NN`); parameter: the window."""

    name = "dtw_1nn"

    def grid(self, quick: bool) -> list[dict]:
        return [{"window": w} for w in ((20,) if quick else (10, 30))]

    def fit(self, segments, params, seed, fidelity=FULL) -> Fitted:
        classes = sorted(segments)
        model = SlidingDTW1NN(window=params["window"]).fit({c: dtw_references(segments[c]) for c in classes})
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
