"""Online CLM segmentation over a fitted frame scorer's evidence (docs/segmentation.md, "Score sources").

:class:`OnlineScoreCLMSegmenter` is the sliding-window warm-started segmenter of :mod:`._segmenters`
with a classifier in place of the UKR manifolds: each new observation is scored from the causal
window of the last ``scorer.window`` observations (:class:`..scorers.WindowScorer`), the scores
become class evidence at the scorer's fitted temperature, and the new observation's pair
compatibilities within H are ``e_im + e_jm − 2/M`` (:func:`..compatibility.evidence_band`).
Everything else — one CLM layer per class plus the background, warm start, confirmed
revisions, segment events — is the UKR segmenter's.  With ``novelty_models`` (class manifolds
from ``handflow train-classes``) each observation's evidence is scaled by its novelty weight
(:func:`..compatibility.novelty_weight`, with the models' intensity ranges, :mod:`..novelty`), so
motion no manifold explains goes to the background; with ``distance_z`` also by the weight of its
feature novelty (:func:`..novelty.distance_weight`, scorers with features only).  With
``null_score`` the background is instead a *null class* that scores ``null_score`` on every
observation (:func:`..compatibility.null_class_evidence`, ``reconstruction="relative"``): the CLM
rejects on the scorer's scale, as the evaluation's ``clm_<scorer>`` (docs/segmentation.md,
"Rejection on the scorer's scale").  :func:`batch_labels` segments a whole recording with the
same compatibilities, the reference of the online/batch agreement.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from ..clm import CLMSegmenter
from ..compatibility import evidence_band, history_compatibility, novelty_weight, null_class_evidence
from ..models import CandidateSet
from ..novelty import distance_weight
from ..scorers import WindowScorer
from ._segmenters import OnlineCLMSegmenter, OnlineUpdate


class OnlineScoreCLMSegmenter(OnlineCLMSegmenter):
    """:class:`._segmenters.OnlineCLMSegmenter` over the class evidence of ``scorer`` (one layer per class).

    Takes the online segmenter's parameters; the UKR-only ones (``error_scale``,
    ``order_rating``, ``pair_error``, ``order_path``, ``min_span``) have no effect; the segment rules
    (``min_progress``, ``max_fit_ratio``) are refused.  ``null_score``: the background is the
    layer of a null class scoring it (module docstring; ``reconstruction`` is then ``"relative"``
    and ``background_factor`` has no effect), instead of the thesis background.
    """

    def __init__(
        self,
        scorer: WindowScorer,
        novelty_models: CandidateSet | None = None,
        novelty: float = 0.25,
        distance_z: float | None = None,
        null_score: float | None = None,
        **params,
    ) -> None:
        self.scorer = scorer
        self.novelty_models = novelty_models
        self.novelty = novelty
        self.distance_z = distance_z
        self.null_score = null_score
        super().__init__(None, **_with_null_class(null_score, novelty_models, distance_z, params))
        if distance_z is not None and not scorer.has_features:
            raise ValueError(f"distance_z needs a scorer with features (minirocket), not {scorer.kind}")
        if self.segment_rules:
            raise ValueError(
                "min_progress and max_fit_ratio need class manifolds' latent time and errors; a scorer's evidence has none"
            )

    def set_params(self, **params):
        """Set parameters as the constructor takes them, and build again as it does: a new
        ``null_score`` brings its reconstruction and the window's null-class column with it."""
        unknown = sorted(set(params) - set(self._get_param_names()))
        if unknown:
            raise ValueError(f"invalid parameters {unknown} for {type(self).__name__}")
        merged = {**self.get_params(deep=False), **params}
        if "null_score" in params and "reconstruction" not in params:
            merged.pop("reconstruction")  # follows the null class (_with_null_class)
        self.__init__(**merged)
        return self

    @classmethod
    def _get_param_names(cls) -> list[str]:
        names = set(OnlineCLMSegmenter._get_param_names()) - {"candidates"}
        return sorted(names | {"scorer", "novelty_models", "novelty", "distance_z", "null_score"})

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
        """The evidence per class (and of the null class, last, with ``null_score``)."""
        return {"evidence": np.zeros((self.window, m + (self.null_score is not None)))}

    def push(self, y: np.ndarray) -> OnlineUpdate:
        """Consume one observation (d,): score its causal window, then re-segment the window."""
        y = self.scorer.check_input(y)[0]
        self._recent.append(y)
        scores, novelty = self.score_last(np.asarray(self._recent))
        return self.update_scores(scores, self.known_weight(y, novelty))

    def score_last(self, recent: np.ndarray) -> tuple[np.ndarray, float | None]:
        """The scores (M,) of the last of the ``recent`` observations, and its feature novelty
        when ``distance_z`` asks for it (else None)."""
        if self.distance_z is None:
            return self.scorer.scores_last(recent), None
        return self.scorer.scores_and_novelty_last(recent)

    def update_scores(self, scores: np.ndarray, known: float | np.ndarray = 1.0) -> OnlineUpdate:
        """:meth:`push` for an observation already scored (M,), with its novelty weights (M,)."""
        self._append(evidence=_evidence(self.scorer, scores, self.null_score)[0] * known)
        return self._segment()

    def known_weight(self, y: np.ndarray, feature_novelty: float | None = None) -> float | np.ndarray:
        """The novelty weights (M,) of the newest observation (its feature novelty given by the
        scorer), averaged over the last H (1 without novelty models and ``distance_z``)."""
        models = self.novelty_models
        if models is None and self.distance_z is None:
            return 1.0
        weight = distance_weight(
            np.atleast_1d(feature_novelty if feature_novelty is not None else 0.0), self.distance_z
        )
        if models is not None:
            stream = self._novelty_stream
            intensity = stream.intensity_weights(y)
            weight = weight * novelty_weight(stream.project(y).errors, models.own_errors, self.novelty, intensity)[0]
        self._weights.append(weight)
        return np.mean(self._weights, axis=0)

    def _updates(self, Y: np.ndarray):
        scores, feature_novelty = _scores(self.scorer, Y, self.distance_z)
        weights = known_weights(self.novelty_models, self.novelty, Y, self.history, feature_novelty, self.distance_z)
        for s, known in zip(scores, weights):
            yield self.update_scores(s, known)


def _with_null_class(
    null_score: float | None, novelty_models: CandidateSet | None, distance_z: float | None, params: dict
) -> dict:
    """The CLM parameters ``params`` with the reconstruction of the rejection: ``"relative"`` with
    a null class (its layer, the evidence's last column, is the background), ``"absolute"`` (the
    thesis background) without; a ValueError for another one, or for a null class together with
    novelty weights."""
    if null_score is not None and (novelty_models is not None or distance_z is not None):
        raise ValueError(
            "null_score rejects on the scorer's scale, novelty_models and distance_z with the background "
            "factor: choose one (docs/segmentation.md)"
        )
    reconstruction = "absolute" if null_score is None else "relative"
    if params.get("reconstruction", reconstruction) != reconstruction:
        raise ValueError(
            f"reconstruction {params['reconstruction']!r} does not apply: over a scorer's evidence the background "
            "is the thesis band ('absolute') or, with null_score, the null class's layer ('relative')"
        )
    return {**params, "reconstruction": reconstruction}


def _evidence(scorer: WindowScorer, scores: np.ndarray, null_score: float | None) -> np.ndarray:
    """Class evidence (N, M) of scores (N, M) at the scorer's temperature, with the null class's
    last (N, M + 1) when ``null_score`` is given."""
    if null_score is None:
        return scorer.evidence(scores)
    return null_class_evidence(np.atleast_2d(scores), null_score, scorer.temperature_)


def _scores(scorer: WindowScorer, Y: np.ndarray, distance_z: float | None) -> tuple[np.ndarray, np.ndarray | None]:
    """The scorer's scores of a recording, and its feature novelty when ``distance_z`` asks for it."""
    return scorer.scores_and_novelty(Y) if distance_z is not None else (scorer.scores(Y), None)


def known_weights(
    models: CandidateSet | None,
    novelty: float,
    Y: np.ndarray,
    history: int,
    feature_novelty: np.ndarray | None = None,
    distance_z: float | None = None,
) -> np.ndarray:
    """Novelty weights (N, M) of a whole recording, each averaged with the H − 1 before it
    (:func:`..compatibility.novelty_weight` times the weight of the frames' feature novelty beyond
    ``distance_z``; all 1 without models and feature novelty)."""
    weights = np.ones((len(Y), 1))
    if models is None and feature_novelty is None:
        return weights
    if feature_novelty is not None:
        weights = distance_weight(feature_novelty, distance_z)[:, None]
    if models is not None:
        weights = weights * novelty_weight(
            models.project(Y).errors, models.own_errors, novelty, models.intensity_weights(Y)
        )
    return history_compatibility(weights, history, 1.0)


def batch_labels(
    scorer: WindowScorer,
    Y: np.ndarray,
    novelty_models: CandidateSet | None = None,
    novelty: float = 0.25,
    distance_z: float | None = None,
    null_score: float | None = None,
    **params,
) -> np.ndarray:
    """Whole-recording CLM over ``scorer``'s evidence at its fitted temperature, scaled by the
    novelty weights of ``novelty_models`` and of the feature novelty beyond ``distance_z`` if given,
    or with the null class of ``null_score`` as the background (class indices, −1 = background);
    ``params`` are :class:`..clm.CLMSegmenter`'s."""
    seg = CLMSegmenter(None, **_with_null_class(null_score, novelty_models, distance_z, params))
    _, span, width = seg.widths()
    scores, feature_novelty = _scores(scorer, Y, distance_z)
    known = known_weights(novelty_models, novelty, Y, int(seg.history), feature_novelty, distance_z)
    evidence = _evidence(scorer, scores, null_score) * known
    return seg.fit_predict_bands(*seg.with_background(evidence_band(evidence, width, span)))
