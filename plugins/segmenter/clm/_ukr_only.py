"""UKR-only recogniser (docs/segmentation.md §A): local + history compatibilities, winner-take-all.

Inherently online: :meth:`UKROnlyRecognizer.push` takes one observation at a time and gives
exactly the values :meth:`UKROnlyRecognizer.predict` computes for the whole sequence.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from sklearn.base import BaseEstimator

from ..base import REJECTED
from ..compatibility import (
    history_compatibility,
    history_weights,
    local_compatibility,
    order_rating,
    overall_compatibility,
    reconstruction_compatibility,
)
from ..models import CandidateSet, Projection


class UKROnlyRecognizer(BaseEstimator):
    """Winner-take-all over ``C(t) = λ C_rec(t) + (1 − λ) C_his(t)`` per candidate.

    An estimator in the project's style (docs/architecture.md): the trained candidates are its
    fitted part; the hyper-parameters are keyword-only, stored as given and checked at first use.

    Parameters
    ----------
    candidates : CandidateSet
        The trained models, one per class.
    lam : float, default 0.3
        λ, weight of the reconstruction compatibility (thesis 0.3).
    gamma : float, default 0.9
        γ, history discount (thesis 0.9).
    history : int, default 10
        H, history length (thesis 5, 10, 15, 20).
    order_rating : {'cos', 'sign'}, default 'cos'
        Latent-order rating (docs/segmentation.md).
    threshold : float or None, default None
        Rejection threshold; observations with ``max C < threshold`` get −1.

    Attributes
    ----------
    classes_ : list of str
        The candidates' class names (column order of C).

    :meth:`fit` only checks the hyper-parameters (nothing is learned); :meth:`predict` and
    :meth:`push` check them at first use too.

    Examples
    --------
    >>> from handflow.plugins.segmenter import LetterGenerator, candidate_set, train_class_models
    >>> ds = LetterGenerator(n_classes=2, random_state=1).dataset((2, 1, 1))
    >>> candidates = candidate_set(train_class_models(ds, n_steps=20, random_state=0))
    >>> Y = ds.test[0].data
    >>> from handflow.plugins.segmenter import UKROnlyRecognizer
    >>> labels = UKROnlyRecognizer(candidates, history=5).fit().predict(Y)
    >>> labels.shape == (len(Y),), set(labels.tolist()) <= {0, 1}
    (True, True)
    """

    def __init__(
        self,
        candidates: CandidateSet,
        *,
        lam: float = 0.3,
        gamma: float = 0.9,
        history: int = 10,
        order_rating: str = "cos",
        threshold: float | None = None,
    ) -> None:
        self.candidates = candidates
        self.lam = lam
        self.gamma = gamma
        self.history = history
        self.order_rating = order_rating
        self.threshold = threshold

    def _check(self) -> None:
        order_rating(self.order_rating)
        history_weights(self.history, self.gamma)
        overall_compatibility(0.0, 0.0, self.lam)

    def fit(self, X=None, y=None) -> UKROnlyRecognizer:
        """Check the hyper-parameters; nothing is learned (the candidates are fitted); returns self."""
        self._check()
        return self

    @property
    def classes_(self) -> list[str]:
        return self.candidates.classes

    # -- batch ------------------------------------------------------------------------------
    def compatibilities_projected(self, proj: Projection) -> np.ndarray:
        """Overall compatibilities C (N, M) of a projected sequence."""
        self._check()
        c_rec = reconstruction_compatibility(proj.errors)
        c_loc = local_compatibility(proj.latent_time, proj.errors, order_rating(self.order_rating))
        return overall_compatibility(c_rec, history_compatibility(c_loc, self.history, self.gamma), self.lam)

    def decide(self, C: np.ndarray) -> np.ndarray:
        """Winner per row of C, −1 where the rejection threshold is not reached."""
        C = np.atleast_2d(C)
        labels = np.argmax(C, axis=1)
        if self.threshold is not None:
            labels = np.where(C.max(axis=1) < self.threshold, REJECTED, labels)
        return labels

    def predict_projected(self, proj: Projection) -> np.ndarray:
        return self.decide(self.compatibilities_projected(proj))

    def predict(self, sequence: np.ndarray) -> np.ndarray:
        """Class index per observation of a (N, d) sequence (−1 = rejected)."""
        return self.predict_projected(self.candidates.project(sequence))

    # -- streaming --------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget the stream history."""
        self._previous_time: np.ndarray | None = None
        self._locals: deque[np.ndarray] = deque(maxlen=self.history)
        self._stream = self.candidates.stream()

    def _start(self) -> None:
        """Check the parameters and start the stream at its first observation."""
        if not hasattr(self, "_locals"):
            self._check()
            self.reset()

    def push(self, y: np.ndarray) -> tuple[int, np.ndarray]:
        """Consume one observation (d,); return (label index or −1, C (M,))."""
        self._start()
        proj = self._stream.project(y)
        return self.update_projected(proj.latent_time[0], proj.errors[0])

    def update(self, y: np.ndarray) -> tuple[int, np.ndarray]:
        """:meth:`push` (its name before the streaming contract, docs/segmentation.md)."""
        return self.push(y)

    def update_projected(self, latent_time: np.ndarray, errors: np.ndarray) -> tuple[int, np.ndarray]:
        """:meth:`push` for an observation already projected onto all candidates."""
        self._start()
        c_rec = reconstruction_compatibility(errors)
        if self._locals.maxlen != self.history:
            self._locals = deque(self._locals, maxlen=self.history)
        rating = order_rating(self.order_rating)
        c_ord = np.zeros_like(c_rec) if self._previous_time is None else rating(latent_time - self._previous_time)
        self._previous_time = np.array(latent_time, dtype=float)
        self._locals.appendleft(0.5 * (c_rec + c_ord))
        w = history_weights(self.history, self.gamma)[: len(self._locals)]
        c_his = np.tensordot(w, np.asarray(self._locals), axes=1) / w.sum()
        C = overall_compatibility(c_rec, c_his, self.lam)
        return int(self.decide(C)[0]), C
