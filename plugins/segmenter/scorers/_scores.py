"""What the sliding-window baselines share (docs/segmentation.md): both classify observation ``t``
from the causal window of the last ``window`` observations (the same temporal context ``H`` the
manifold methods get), both z-score the data with the training mean and std (documented choice),
and both expose per-class scores (higher = better) so that a rejection threshold and a reduced
class set (left-out experiment) are cheap to apply.
"""

from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator

from ..base import REJECTED


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
