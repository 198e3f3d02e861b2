"""Online CLM segmentation over a fitted frame scorer's evidence (docs/segmentation.md, "Score sources").

:class:`OnlineScoreCLMSegmenter` is the sliding-window warm-started segmenter of :mod:`.online`
with a classifier in place of the UKR manifolds: each new observation is scored from the causal
window of the last ``scorer.window`` observations (:class:`.scorers.WindowScorer`), the scores
become class evidence at the scorer's fitted temperature, and the new observation's pair
compatibilities within H are ``e_im + e_jm − 2/M`` (:func:`.compatibility.evidence_band`).
Everything else — one CLM layer per class plus the background, warm start, confirmed
revisions, segment events — is the UKR segmenter's.  With ``novelty_models`` (class manifolds
from ``handflow train-classes``) each observation's evidence is scaled by its novelty weight
(:func:`.compatibility.novelty_weight`, with the models' intensity ranges, :mod:`.intensity`), so
motion no manifold explains goes to the background.
:func:`batch_labels` segments a whole recording with the same compatibilities, the reference of
the online/batch agreement.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from .candidates import CandidateSet
from .clm_segmenter import CLMSegmenter
from .compatibility import evidence_band, history_compatibility, novelty_weight
from .online import OnlineCLMSegmenter, OnlineUpdate
from .scorers import WindowScorer


class OnlineScoreCLMSegmenter(OnlineCLMSegmenter):
    """:class:`.online.OnlineCLMSegmenter` over the class evidence of ``scorer`` (one layer per class).

    Takes the online segmenter's parameters; the UKR-only ones (``error_scale``,
    ``order_rating``, ``pair_error``, ``order_path``, ``min_span``) have no effect; the segment rules
    (``min_progress``, ``max_fit_ratio``) are refused.
    """

    def __init__(
        self, scorer: WindowScorer, novelty_models: CandidateSet | None = None, novelty: float = 0.25, **params
    ) -> None:
        self.scorer = scorer
        self.novelty_models = novelty_models
        self.novelty = novelty
        super().__init__(None, **params)
        if self.segment_rules:
            raise ValueError(
                "min_progress and max_fit_ratio need class manifolds' latent time and errors; a scorer's evidence has none"
            )

    @classmethod
    def _get_param_names(cls) -> list[str]:
        names = set(OnlineCLMSegmenter._get_param_names()) - {"candidates"}
        return sorted(names | {"scorer", "novelty_models", "novelty"})

    @property
    def classes_(self) -> list[str]:
        return [str(c) for c in self.scorer.classes_]

    def _n_layers(self) -> int:
        return len(self.scorer.classes_)

    def reset(self) -> None:
        super().reset()
        self._recent: deque[np.ndarray] = deque(maxlen=int(self.scorer.window))
        self._novelty_stream = self.novelty_models.stream() if self.novelty_models is not None else None
        self._weights: deque[np.ndarray] = deque(maxlen=int(self.history))  # novelty weights of the last H observations

    def _source_rows(self, m: int) -> dict[str, np.ndarray]:
        return {"evidence": np.zeros((self.window, m))}

    def update(self, y: np.ndarray) -> OnlineUpdate:
        """Consume one observation (d,): score its causal window, then re-segment the window."""
        y = self.scorer.check_input(y)[0]
        self._recent.append(y)
        return self.update_scores(self.scorer.scores_last(np.asarray(self._recent)), self.known_weight(y))

    def update_scores(self, scores: np.ndarray, known: float | np.ndarray = 1.0) -> OnlineUpdate:
        """:meth:`update` for an observation already scored (M,), with its novelty weights (M,)."""
        self._append(evidence=self.scorer.evidence(scores)[0] * known)
        return self._segment()

    def known_weight(self, y: np.ndarray) -> float | np.ndarray:
        """The novelty weights (M,) of the newest observation, averaged over the last H (1 without novelty models)."""
        models = self.novelty_models
        if models is None:
            return 1.0
        stream = self._novelty_stream
        intensity = stream.intensity_weights(y)
        self._weights.append(novelty_weight(stream.project(y).errors, models.own_errors, self.novelty, intensity)[0])
        return np.mean(self._weights, axis=0)

    def _updates(self, Y: np.ndarray):
        weights = known_weights(self.novelty_models, self.novelty, Y, self.history)
        for s, known in zip(self.scorer.scores(Y), weights):
            yield self.update_scores(s, known)


def known_weights(models: CandidateSet | None, novelty: float, Y: np.ndarray, history: int) -> np.ndarray:
    """Novelty weights (N, M) of a whole recording, each averaged with the H − 1 before it
    (:func:`.compatibility.novelty_weight`; all 1 without models)."""
    if models is None:
        return np.ones((len(Y), 1))
    weights = novelty_weight(models.project(Y).errors, models.own_errors, novelty, models.intensity_weights(Y))
    return history_compatibility(weights, history, 1.0)


def batch_labels(
    scorer: WindowScorer, Y: np.ndarray, novelty_models: CandidateSet | None = None, novelty: float = 0.25, **params
) -> np.ndarray:
    """Whole-recording CLM over ``scorer``'s evidence at its fitted temperature, scaled by the
    novelty weights of ``novelty_models`` if given (class indices, −1 = background); ``params``
    are :class:`.clm_segmenter.CLMSegmenter`'s."""
    seg = CLMSegmenter(None, **params)
    _, span, width = seg.widths()
    evidence = scorer.evidence(scorer.scores(Y)) * known_weights(novelty_models, novelty, Y, int(seg.history))
    return seg.fit_predict_bands(*seg.with_background(evidence_band(evidence, width, span)))
