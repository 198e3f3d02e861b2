"""Baseline point-wise classifiers for the evaluation: sliding-window DTW 1-NN and
per-class HMMs.

Both classify observation ``t`` from the causal window of the last ``window`` observations
(the same temporal context ``H`` the manifold methods get), both z-score the data with the
training mean and std (documented choice), and both expose per-class scores (higher = better)
so that a rejection threshold and a reduced class set (left-out experiment) are cheap to apply.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.special import logsumexp
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted

from ..base import REJECTED


@numba.njit(cache=True)
def _subsequence_dtw(Q, R):  # pragma: no cover - compiled
    """Open-begin/open-end DTW of query Q (w, d) inside reference R (n, d): min accumulated cost."""
    w, n = Q.shape[0], R.shape[0]
    prev = np.empty(n)
    cur = np.empty(n)
    for j in range(n):
        c = 0.0
        for k in range(Q.shape[1]):
            diff = Q[0, k] - R[j, k]
            c += diff * diff
        prev[j] = np.sqrt(c)
    for i in range(1, w):
        for j in range(n):
            c = 0.0
            for k in range(Q.shape[1]):
                diff = Q[i, k] - R[j, k]
                c += diff * diff
            best = prev[j]
            if j > 0:
                if cur[j - 1] < best:
                    best = cur[j - 1]
                if prev[j - 1] < best:
                    best = prev[j - 1]
            cur[j] = np.sqrt(c) + best
        prev, cur = cur, prev
    return prev.min()


@numba.njit(cache=True)
def _sliding_dtw(Y, refs, offsets, window):  # pragma: no cover - compiled
    """Distance (N, n_refs) of each causal window of Y to each reference, per query point."""
    N = Y.shape[0]
    out = np.empty((N, offsets.shape[0] - 1))
    for t in range(N):
        lo = max(0, t - window + 1)
        Q = Y[lo : t + 1]
        for r in range(offsets.shape[0] - 1):
            out[t, r] = _subsequence_dtw(Q, refs[offsets[r] : offsets[r + 1]]) / Q.shape[0]
    return out


class _Standardiser(BaseEstimator):
    def fit_from(self, sequences: list[np.ndarray]) -> None:
        Y = np.vstack(sequences)
        self.mean_ = Y.mean(axis=0)
        std = Y.std(axis=0)
        self.std_ = np.where(std > 0, std, 1.0)

    def standardise(self, Y: np.ndarray) -> np.ndarray:
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        if Y.shape[1] != self.mean_.size:
            raise ValueError(f"observations must have {self.mean_.size} columns, got {Y.shape[1]}")
        return (Y - self.mean_) / self.std_


def _check_window(window: int) -> None:
    if int(window) < 1:
        raise ValueError(f"window must be >= 1, got {window}")


def decide(scores: np.ndarray, threshold: float | None = None) -> np.ndarray:
    """Winner per row of ``scores`` (higher = better); −1 where the best score < threshold."""
    labels = np.argmax(scores, axis=1)
    if threshold is not None:
        labels = np.where(scores.max(axis=1) < threshold, REJECTED, labels)
    return labels


class SlidingDTW1NN(_Standardiser):
    """1-nearest-neighbour over training sequences with open-begin/end subsequence DTW.

    Score of class c at ``t`` = − min over c's training sequences of the DTW cost of the window
    ``y_{t−w+1…t}`` divided by its length.  ``threshold`` (on that score) rejects.
    """

    def __init__(self, *, window: int = 10, threshold: float | None = None) -> None:
        self.window = window
        self.threshold = threshold

    def fit(self, sequences_by_class: dict[str, list[np.ndarray]]) -> SlidingDTW1NN:
        _check_window(self.window)
        if not sequences_by_class:
            raise ValueError("need at least one class with training sequences")
        self.classes_ = list(sequences_by_class)
        self.fit_from([s for seqs in sequences_by_class.values() for s in seqs])
        refs, owner = [], []
        for c, seqs in enumerate(sequences_by_class.values()):
            refs += [self.standardise(s) for s in seqs]
            owner += [c] * len(seqs)
        self.refs_ = np.ascontiguousarray(np.vstack(refs))
        self.offsets_ = np.r_[0, np.cumsum([len(r) for r in refs])].astype(np.int64)
        self.owner_ = np.asarray(owner)
        return self

    def scores(self, Y: np.ndarray) -> np.ndarray:
        """(N, M) class scores."""
        check_is_fitted(self, "refs_")
        _check_window(self.window)
        d = _sliding_dtw(np.ascontiguousarray(self.standardise(Y)), self.refs_, self.offsets_, int(self.window))
        out = np.full((d.shape[0], len(self.classes_)), -np.inf)
        for c in range(len(self.classes_)):
            out[:, c] = -d[:, self.owner_ == c].min(axis=1)
        return out

    def predict(self, Y: np.ndarray) -> np.ndarray:
        return decide(self.scores(Y), self.threshold)


class PerClassHMM(_Standardiser):
    """One Gaussian HMM (hmmlearn, diagonal covariances) per class; score = mean log-likelihood
    per observation of the causal window ``y_{t−w+1…t}`` (windowed forward algorithm)."""

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
