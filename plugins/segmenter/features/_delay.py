"""Causal delay embedding of observations for the class manifolds (docs/segmentation.md,
"Continuous recordings").

A single frame of a real sensor stream (one accelerometer/gyroscope sample, one skeleton pose)
says little about the motion it belongs to; its recent past does.  :class:`DelayEmbedding` maps
frame ``t`` to ``[y_{t−(w−1)s}, …, y_{t−s}, y_t]`` (``w`` frames ``s`` apart, oldest first), so a
class manifold learns a short stretch of trajectory.  The embedding is causal, so a stream
embedded sample by sample (:meth:`DelayEmbedding.stream`) equals the whole recording embedded at
once; before the stream holds ``(w − 1)·s`` frames, the missing past repeats the first frame
(documented choice).  Training segments use only complete windows (:meth:`DelayEmbedding.complete`).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DelayEmbedding:
    """``window`` frames, ``step`` frames apart; ``window=1`` is the identity."""

    window: int = 1
    step: int = 1

    def __post_init__(self) -> None:
        if int(self.window) < 1 or int(self.step) < 1:
            raise ValueError(f"delay window and step must be >= 1, got window={self.window}, step={self.step}")

    @property
    def span(self) -> int:
        """Frames of past one embedded frame reaches back."""
        return (int(self.window) - 1) * int(self.step)

    def fit(self, X=None, y=None) -> DelayEmbedding:
        """Nothing to learn: the embedding is fixed by its parameters (the streaming contract)."""
        return self

    def transform(self, X: np.ndarray) -> np.ndarray:
        """(T, d) → (T, window·d), causal; the first frame stands in for the missing past."""
        X = np.asarray(X, dtype=float)
        if self.window == 1:
            return X
        lags = np.arange(self.window - 1, -1, -1) * self.step
        idx = np.clip(np.arange(len(X))[:, None] - lags[None, :], 0, None)
        return X[idx].reshape(len(X), -1)

    def complete(self, X: np.ndarray) -> np.ndarray:
        """The embedded frames whose window lies inside X (all of them when X is too short)."""
        E = self.transform(X)
        return E[self.span :] if len(X) > self.span else E

    def stream(self) -> DelayStream:
        """A sample-by-sample embedder equal to :meth:`transform` of the whole stream."""
        return DelayStream(self)

    def to_provenance(self) -> dict:
        return {"delay_window": int(self.window), "delay_step": int(self.step)}

    @classmethod
    def from_provenance(cls, provenance: dict | None) -> DelayEmbedding:
        p = provenance or {}
        return cls(int(p.get("delay_window", 1)), int(p.get("delay_step", 1)))


class DelayStream:
    """Embeds one frame at a time (see :meth:`DelayEmbedding.stream`)."""

    def __init__(self, delay: DelayEmbedding) -> None:
        self.delay = delay
        self._past: deque[np.ndarray] = deque(maxlen=delay.span + 1)

    def push(self, y: np.ndarray) -> np.ndarray:
        """The embedded frame (window·d,) of the newest observation y (d,)."""
        y = np.asarray(y, dtype=float).reshape(-1)
        if not self._past:
            self._past.extend([y] * (self.delay.span + 1))
        else:
            self._past.append(y)
        past = np.asarray(self._past)
        return past[:: -int(self.delay.step)][: self.delay.window][::-1].reshape(-1)
