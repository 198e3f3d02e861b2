"""Per-class Gaussian HMMs scored over the causal window, a baseline of the evaluation
(docs/segmentation.md)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from scipy.special import logsumexp
from sklearn.utils.validation import check_is_fitted

from ._scores import _check_window, _Standardiser, decide


class PerClassHMM(_Standardiser):
    """One Gaussian HMM (hmmlearn, diagonal covariances) per class; score = mean log-likelihood
    per observation of the causal window ``y_{t−w+1…t}`` (windowed forward algorithm).

    Parameters
    ----------
    n_states : int, default 4
        Hidden states per class.
    window : int, default 10
        w, frames of the causal window.
    n_iter : int, default 30
        EM iterations of each HMM.
    min_covar : float, default 1e-2
        Floor of the diagonal covariances (standardised units).
    threshold : float or None, default None
        Frames whose best score is below it are rejected (−1) by :meth:`predict`.
    random_state : int or None, default 0
        Seed of the HMMs' initialisation.

    Attributes
    ----------
    classes_ : list of str
        Class names, the score columns' order.
    mean_, std_ : ndarray of shape (d,)
        Standardisation of the training frames.
    models_ : list of hmmlearn.hmm.GaussianHMM
        One fitted HMM per class.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 4 * np.pi, 40)
    >>> train = {"circle": [np.c_[np.sin(t), np.cos(t)]], "line": [np.c_[t, t]]}
    >>> from handflow.plugins.segmenter.scorers import PerClassHMM
    >>> hmm = PerClassHMM(n_states=2, n_iter=5, window=5, random_state=0).fit(train)
    >>> hmm.scores(train["circle"][0]).shape
    (40, 2)
    """

    requires: ClassVar[dict[str, str]] = {"hmmlearn": "hmm"}  # module → the extra that installs it

    def __init__(
        self,
        *,
        n_states: int = 4,
        window: int = 10,
        n_iter: int = 30,
        min_covar: float = 1e-2,
        threshold: float | None = None,
        random_state: int | None = 0,
    ) -> None:
        self.n_states = n_states
        self.window = window
        self.n_iter = n_iter
        self.min_covar = min_covar
        self.threshold = threshold
        self.random_state = random_state

    def fit(self, sequences_by_class: dict[str, list[np.ndarray]]) -> PerClassHMM:
        _check_window(self.window)
        if int(self.n_states) < 1:
            raise ValueError(f"n_states must be >= 1, got {self.n_states}")
        if not sequences_by_class:
            raise ValueError("need at least one class with training sequences")
        try:
            from hmmlearn.hmm import GaussianHMM
        except ImportError:
            raise ImportError("the HMM baseline needs hmmlearn: pip install 'handflow[hmm]'") from None
        self.classes_ = list(sequences_by_class)
        self.fit_from([s for seqs in sequences_by_class.values() for s in seqs])
        self.models_ = []
        for seqs in sequences_by_class.values():
            Z = [self.standardise(s) for s in seqs]
            m = GaussianHMM(
                n_components=self.n_states,
                covariance_type="diag",
                n_iter=self.n_iter,
                min_covar=self.min_covar,
                random_state=self.random_state,
            )
            m.fit(np.vstack(Z), [len(z) for z in Z])
            self.models_.append(m)
        return self

    @staticmethod
    def _emission_logprob(m, Z: np.ndarray) -> np.ndarray:
        var = np.diagonal(m.covars_, axis1=1, axis2=2)  # (K, d)
        diff = Z[:, None, :] - m.means_[None]
        return -0.5 * (np.sum(diff * diff / var, axis=2) + np.sum(np.log(2 * np.pi * var), axis=1))

    def _window_loglik(self, m, Z: np.ndarray) -> np.ndarray:
        logB = self._emission_logprob(m, Z)
        logA = np.log(np.maximum(m.transmat_, 1e-300))
        N = Z.shape[0]
        t = np.arange(N)
        start = np.maximum(0, t - self.window + 1)
        length = t - start + 1
        alpha = np.log(np.maximum(m.startprob_, 1e-300))[None] + logB[start]
        for s in range(1, self.window):
            active = s < length
            if not active.any():
                break
            step = logsumexp(alpha[active][:, :, None] + logA[None], axis=1) + logB[start[active] + s]
            alpha[active] = step
        return logsumexp(alpha, axis=1) / length

    def scores(self, Y: np.ndarray) -> np.ndarray:
        """(N, M) class scores."""
        check_is_fitted(self, "models_")
        _check_window(self.window)
        Z = self.standardise(Y)
        return np.stack([self._window_loglik(m, Z) for m in self.models_], axis=1)

    def predict(self, Y: np.ndarray) -> np.ndarray:
        return decide(self.scores(Y), self.threshold)
