"""Per-channel scaling of observations, learned on training data and stored with each class model.

UKR projects by Euclidean distance, so a channel with a small numeric range (the letters' force
channel: std 0.39 against 13 for the pen position) is ignored by the projection while the
normalised error ``e_t`` (divided by the training variance) is dominated by it.  Documented
choice (docs/segmentation.md): every channel is z-scored with the mean and standard deviation of
*all* training observations of all classes — one scaling for the whole model set, so every
candidate projects in the same metric.  The scaling is written into each model's provenance
(``channel_offset``, ``channel_scale``) and survives save/load.
"""

from __future__ import annotations

import numpy as np

MIN_SCALE = 1e-8


class ChannelScaling:
    """``(y − offset_) / scale_`` per channel (sklearn conventions: ``fit`` learns the ``_`` attributes)."""

    def __init__(self, offset=None, scale=None) -> None:
        if offset is not None:
            self.offset_ = np.asarray(offset, dtype=float).reshape(-1)
            self.scale_ = np.asarray(scale, dtype=float).reshape(-1)
            if self.offset_.shape != self.scale_.shape or not (self.scale_ > 0).all():
                raise ValueError("channel scaling needs one offset and one positive scale per channel")

    def fit(self, sequences: list[np.ndarray]) -> ChannelScaling:
        Y = np.vstack([np.asarray(s, dtype=float) for s in sequences])
        if not np.isfinite(Y).all():
            raise ValueError("training data hold NaN/inf; repair them before training")
        self.offset_ = Y.mean(axis=0)
        std = Y.std(axis=0)
        self.scale_ = np.where(std > MIN_SCALE, std, 1.0)
        return self

    def transform(self, Y: np.ndarray) -> np.ndarray:
        Y = np.asarray(Y, dtype=float)
        if Y.shape[-1] != self.offset_.size:
            raise ValueError(
                f"observations have {Y.shape[-1]} channels, the models were trained on {self.offset_.size}"
            )
        return (Y - self.offset_) / self.scale_

    def stream(self) -> ScalingStream:
        """A sample-by-sample scaler equal to :meth:`transform` (it keeps no state)."""
        return ScalingStream(self)

    def inverse_transform(self, Z: np.ndarray) -> np.ndarray:
        """Scaled observations back in the raw channel units."""
        return self.offset_ + self.scale_ * np.asarray(Z, dtype=float)

    def to_provenance(self) -> dict:
        return {"channel_offset": self.offset_.tolist(), "channel_scale": self.scale_.tolist()}

    @classmethod
    def from_model(cls, model) -> ChannelScaling | None:
        """The scaling stored with a trained model, or None (models trained on raw channels)."""
        prov = getattr(model, "provenance_", None) or {}
        if "channel_scale" not in prov:
            return None
        return cls(prov["channel_offset"], prov["channel_scale"])

    def same_as(self, other: ChannelScaling | None) -> bool:
        return (
            other is not None
            and np.array_equal(self.offset_, other.offset_)
            and np.array_equal(self.scale_, other.scale_)
        )


class ScalingStream:
    """Scales one frame at a time (see :meth:`ChannelScaling.stream`)."""

    def __init__(self, scaling: ChannelScaling) -> None:
        self.scaling = scaling

    def push(self, y: np.ndarray) -> np.ndarray:
        """The scaled frame (d,) of the newest observation y (d,)."""
        return self.scaling.transform(np.asarray(y, dtype=float).reshape(-1))
