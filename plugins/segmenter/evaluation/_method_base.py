"""The base of the evaluation's methods (docs/segmentation.md): a fitted model over the known
classes, the registry entry's protocol (:class:`Method`) and the methods with per-frame class
scores (:class:`ScoreMethod`).

A method is fitted on training segments per known class (global class indices),
then labels a recording in two stages: :meth:`~ScoreMethod.prepare` does the expensive part once
(projection onto the class manifolds, window scores), :meth:`~ScoreMethod.labels` applies one
value of the method's *rejection parameter* — a score threshold for the classifiers and the CLM
over their scores, the background strength for the UKR/CLM — optionally with one class removed from the model set (the
pseudo-unknown of the calibration).  Labels are global class indices, ``−1`` = rejected.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from ..base import REJECTED
from ..scorers import decide
from ._fidelity import FULL, Fidelity
from ._metrics import score_thresholds, threshold_labels


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
    cheaper_fits = True  # a fidelity changes its fitted models (the class manifolds have cheaper forms)


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
    cheaper_fits = False  # every fidelity fits the same model: the screen's fits are the refinement's

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
        the fit may spend (:mod:`._selection`; only the class manifolds have a cheaper form, :attr:`Method.cheaper_fits`)."""

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
