"""Heading channels: the direction of motion of chosen channels, appended to every observation
(docs/segmentation.md, "Heading channels").

A pen (or hand) trajectory's *shape* is carried by where it heads, whatever its size: a small
``u`` heads the same way as a large one, while its positions lie inside the large one's.
:class:`Headings` appends to observation ``t`` the soft unit vector of the chosen channels' step
``v_t = y_t − y_{t−1}``, ``v_t / sqrt(|v_t|² + σ²)``; the softness ``σ`` (documented choice:
0.2 of the median training step, :meth:`Headings.fit`) fades the heading out where the motion
nearly stops and its direction is noise.  The first observation of a sequence has no step and
gets heading 0.  Headings are causal, so a stream headed sample by sample
(:meth:`Headings.stream`) equals the whole sequence headed at once.

:meth:`Headings.reversed` turns the headings round: the same observations traversed backward.
A candidate that fits those better than any candidate fits them forward shows a motion played
in reverse (:func:`..compatibility.reject_poor_fit`).
"""

from __future__ import annotations

import operator
from dataclasses import dataclass

import numpy as np

from ._derived import FrameSteps

SOFTNESS_OF_MEDIAN_STEP = 0.2  # σ as a fraction of the median training step (documented choice)


@dataclass(unsafe_hash=True)
class Headings:
    """Headings of ``channels`` (column indices) with softness ``softness``; no channels = off.
    :meth:`fit` learns the softness from training sequences (the streaming contract)."""

    channels: tuple[int, ...] = ()
    softness: float = 0.0

    def __post_init__(self) -> None:
        if len(set(self.channels)) != len(self.channels) or any(int(c) < 0 for c in self.channels):
            raise ValueError(f"heading channels must be distinct column indices >= 0, got {list(self.channels)}")
        if not np.isfinite(self.softness) or self.softness < 0:
            raise ValueError(f"heading softness must be finite and >= 0, got {self.softness}")

    @property
    def active(self) -> bool:
        return bool(self.channels)

    def fit(self, sequences: list[np.ndarray], y=None) -> Headings:
        """Set the softness to :data:`SOFTNESS_OF_MEDIAN_STEP` of the median step length of the
        heading channels over the training ``sequences``; returns the headings."""
        channels = self.channels = tuple(int(c) for c in self.channels)
        if not channels:
            self.softness = 0.0
            return self
        width = min(np.asarray(s).shape[1] for s in sequences)
        if max(channels) >= width:
            raise ValueError(f"heading channel {max(channels)} does not exist: observations have {width} channels")
        steps = np.concatenate(
            [np.linalg.norm(np.diff(np.asarray(s, float)[:, channels], axis=0), axis=1) for s in sequences]
        )
        self.softness = SOFTNESS_OF_MEDIAN_STEP * float(np.median(steps)) if steps.size else 0.0
        return self

    def headings(self, steps: np.ndarray) -> np.ndarray:
        """Soft unit vectors of steps (N, c)."""
        length = np.sqrt(np.sum(steps * steps, axis=1, keepdims=True) + self.softness**2)
        return np.divide(steps, length, out=np.zeros_like(steps), where=length > 0)

    def transform(self, Y: np.ndarray) -> np.ndarray:
        """(T, d) → (T, d + c): every observation with its heading appended."""
        Y = np.asarray(Y, dtype=float)
        if not self.active:
            return Y
        self.check_width(Y.shape[-1])
        picked = Y[:, list(self.channels)]
        steps = np.diff(picked, axis=0, prepend=picked[:1])
        return np.hstack([Y, self.headings(steps)])

    def check_width(self, width: int) -> None:
        """Refuse observations that lack a heading channel."""
        if max(self.channels) >= width:
            raise ValueError(
                f"observations have {width} channels, the models head channel {max(self.channels)}; "
                "give them the channels the models were trained on"
            )

    def reversed(self, Z: np.ndarray) -> np.ndarray:
        """Headed observations (T, d + c) with their headings turned round (traversed backward)."""
        Z = np.array(Z, dtype=float)
        if self.active:
            Z[..., Z.shape[-1] - len(self.channels) :] *= -1.0
        return Z

    def stream(self) -> HeadingStream:
        """A sample-by-sample headings equal to :meth:`transform` of the whole stream."""
        return HeadingStream(self)

    def to_provenance(self) -> dict:
        return {"heading_channels": [int(c) for c in self.channels], "heading_softness": float(self.softness)}

    @classmethod
    def from_provenance(cls, provenance: dict | None) -> Headings:
        """The headings a model's provenance records (none when it records none)."""
        p = provenance or {}
        channels, softness = p.get("heading_channels", ()), p.get("heading_softness", 0.0)
        try:
            if isinstance(channels, (str, bytes)) or isinstance(softness, (str, bytes, bool)):
                raise TypeError
            return cls(tuple(operator.index(c) for c in channels), float(softness))
        except (TypeError, ValueError, OverflowError):
            raise ValueError(
                f"the model file records bad heading channels {channels!r} / softness {softness!r}; "
                "retrain the models with `handflow train-classes`"
            ) from None


class HeadingStream:
    """Heads one observation at a time (see :meth:`Headings.stream`)."""

    def __init__(self, headings: Headings) -> None:
        self.spec = headings
        self._steps = FrameSteps()

    def push(self, y: np.ndarray) -> np.ndarray:
        """The observation (d,) with its heading appended (d + c,)."""
        y = np.asarray(y, dtype=float).reshape(-1)
        if not self.spec.active:
            return y
        self.spec.check_width(y.size)
        step = self._steps.push(y[list(self.spec.channels)])
        return np.concatenate([y, self.spec.headings(step[None])[0]])
