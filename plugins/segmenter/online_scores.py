"""Online CLM segmentation over a fitted frame scorer's evidence (docs/segmentation.md, "Score sources").

:class:`OnlineScoreCLMSegmenter` is the sliding-window warm-started segmenter of :mod:`.online`
with a classifier in place of the UKR manifolds: each new observation is scored from the causal
window of the last ``scorer.window`` observations (:class:`.scorers.WindowScorer`), the scores
become class evidence at the scorer's fitted temperature, and the new observation's pair
compatibilities within H are ``e_im + e_jm − 2/M`` (:func:`.compatibility.evidence_band`).
Everything else — one CLM layer per class plus the background, warm start, confirmed
revisions, segment events — is the UKR segmenter's.  :func:`batch_labels` segments a whole
recording with the same compatibilities, the reference of the online/batch agreement.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from .clm_segmenter import CLMSegmenter
from .compatibility import evidence_band
from .online import OnlineCLMSegmenter, OnlineUpdate
from .scorers import WindowScorer


class OnlineScoreCLMSegmenter(OnlineCLMSegmenter):
    """:class:`.online.OnlineCLMSegmenter` over the class evidence of ``scorer`` (one layer per class).

    Takes the online segmenter's parameters; the UKR-only ones (``error_scale``,
    ``order_rating``, ``pair_error``, ``order_path``, ``min_span``) have no effect.
    """

    def __init__(self, scorer: WindowScorer, **params) -> None:
        self.scorer = scorer
        super().__init__(None, **params)

    @classmethod
    def _get_param_names(cls) -> list[str]:
        return sorted((set(OnlineCLMSegmenter._get_param_names()) - {"candidates"}) | {"scorer"})

    @property
    def classes_(self) -> list[str]:
        return [str(c) for c in self.scorer.classes_]

    def _n_layers(self) -> int:
        return len(self.scorer.classes_)

    def reset(self) -> None:
        super().reset()
        self._recent: deque[np.ndarray] = deque(maxlen=int(self.scorer.window))

    def _source_rows(self, m: int) -> dict[str, np.ndarray]:
        return {"evidence": np.zeros((self.window, m))}

    def update(self, y: np.ndarray) -> OnlineUpdate:
        """Consume one observation (d,): score its causal window, then re-segment the window."""
        y = self.scorer.check_input(y)[0]
        self._recent.append(y)
        return self.update_scores(self.scorer.scores_last(np.asarray(self._recent)))

    def update_scores(self, scores: np.ndarray) -> OnlineUpdate:
        """:meth:`update` for an observation already scored (M,)."""
        self._append(evidence=self.scorer.evidence(scores)[0])
        return self._segment()

    def _updates(self, Y: np.ndarray):
        for s in self.scorer.scores(Y):
            yield self.update_scores(s)


def batch_labels(scorer: WindowScorer, Y: np.ndarray, **params) -> np.ndarray:
    """Whole-recording CLM over ``scorer``'s evidence at its fitted temperature (class indices,
    −1 = background); ``params`` are :class:`.clm_segmenter.CLMSegmenter`'s."""
    seg = CLMSegmenter(None, **params)
    _, span, width = seg.widths()
    evidence = scorer.evidence(scorer.scores(Y))
    return seg.fit_predict_bands(*seg.with_background(evidence_band(evidence, width, span)))
