"""The streaming contract of every causal transform (docs/segmentation.md, "Streaming contract").

A transform is fitted on training data (``fit`` returns the transform; what it learns ends in
``_``), transforms a whole recording at once (``transform``) and gives a per-sample object
(``stream()``) whose ``push`` turns one frame into the same row ``transform`` gives for it.
The online segmenters' per-sample method is ``push`` too.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class SampleStream(Protocol):
    """One frame in, its transformed (or recognised) row out, state kept between frames."""

    def push(self, y: np.ndarray): ...


@runtime_checkable
class CausalTransform(Protocol):
    """``fit`` → ``transform`` of a whole recording, or ``stream()`` → ``push`` frame by frame."""

    def fit(self, X, y=None): ...

    def transform(self, X: np.ndarray) -> np.ndarray: ...

    def stream(self) -> SampleStream: ...
