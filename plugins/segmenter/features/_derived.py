"""Derived features of continuous recordings: velocities appended to every frame
(docs/segmentation.md, "Continuous recordings").

``Derived("velocities")`` appends to every frame the step from the frame before, ``x_t − x_{t−1}``
of every channel (the first frame of a stream gets step 0; training segments use only frames
with a true step, :meth:`Derived.complete`).  The step is taken per frame, not per second:
recordings of one dataset share a nominal rate, and the scaling that follows (z-scored or
running, :mod:`._running_scaling`) gives the new channels unit spread anyway.  The steps are
causal, so a stream derived sample by sample (:meth:`Derived.stream`) equals the whole recording
derived at once.  The evaluation chooses the derived features on validation like a method's
parameters; class models record theirs in their provenance and derive them from raw streams.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DERIVED = ("none", "velocities")


@dataclass(frozen=True)
class Derived:
    """Derived features ``kind`` (one of :data:`DERIVED`)."""

    kind: str = "none"

    def __post_init__(self) -> None:
        if self.kind not in DERIVED:
            raise ValueError(f"derived features must be one of {DERIVED}, got {self.kind!r}")

    @property
    def active(self) -> bool:
        return self.kind != "none"

    @property
    def factor(self) -> int:
        """Channels out per channel in."""
        return 2 if self.active else 1

    def fit(self, X=None, y=None) -> Derived:
        """Nothing to learn: a derived feature is fixed by its parameters (the streaming contract)."""
        return self

    def transform(self, X: np.ndarray) -> np.ndarray:
        """Frames (T, d) with the derived features appended: (T, factor·d)."""
        X = np.asarray(X, dtype=float)
        if not self.active:
            return X
        return np.hstack([X, np.diff(X, axis=0, prepend=X[:1])])

    def complete(self, X: np.ndarray) -> np.ndarray:
        """The derived frames of a segment that have a true step (all but the first)."""
        D = self.transform(X)
        return D[1:] if self.active and len(D) > 1 else D

    def stream(self) -> DerivedStream:
        return DerivedStream(self)

    def to_provenance(self) -> dict:
        return {"derived": self.kind}

    @classmethod
    def from_provenance(cls, provenance: dict | None) -> Derived:
        """The derived features a model's provenance records (none when it records none)."""
        kind = (provenance or {}).get("derived", "none")
        if kind not in DERIVED:  # also refuses non-strings: nothing else is in DERIVED
            raise ValueError(
                f"the model file records derived features {kind!r}, not one of {DERIVED}; "
                "retrain the models with `handflow train-classes`"
            )
        return cls(kind)


def derive(X: np.ndarray, kind: str) -> np.ndarray:
    """Frames (T, d) with the derived features ``kind`` appended (:meth:`Derived.transform`)."""
    return Derived(kind).transform(X)


class FrameSteps:
    """The step of each pushed frame from the one before (0 for the first): the causal difference
    that velocities (:class:`DerivedStream`) and headings (:mod:`._headings`) are made of."""

    def __init__(self) -> None:
        self._last: np.ndarray | None = None

    def push(self, y: np.ndarray) -> np.ndarray:
        step = y - (y if self._last is None else self._last)
        self._last = y
        return step


class DerivedStream:
    """Derives one frame at a time (see :meth:`Derived.stream`)."""

    def __init__(self, derived: Derived) -> None:
        self.spec = derived
        self._steps = FrameSteps()

    def push(self, y: np.ndarray) -> np.ndarray:
        """The frame (d,) with its derived features (factor·d,)."""
        y = np.asarray(y, dtype=float).reshape(-1)
        if not self.spec.active:
            return y
        return np.concatenate([y, self._steps.push(y)])
