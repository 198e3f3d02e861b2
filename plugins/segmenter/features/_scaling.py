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
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted

MIN_SCALE = 1e-8


class ChannelScaling(BaseEstimator):
    """Per-channel z-scoring ``(y − offset_) / scale_`` learned on training sequences.

    An estimator in the project's style (docs/architecture.md, "Estimator style"): it has no
    hyper-parameters; :meth:`fit` learns the ``_`` attributes, and a scaling stored with class
    models comes back through :meth:`fitted` (:meth:`from_model`).

    Attributes
    ----------
    offset_ : ndarray of shape (n_channels,)
        Mean of every channel over all training observations.
    scale_ : ndarray of shape (n_channels,)
        Standard deviation of every channel (1 where it is below :data:`MIN_SCALE`).

    Examples
    --------
    >>> import numpy as np
    >>> from handflow.plugins.segmenter.features import ChannelScaling
    >>> s = ChannelScaling().fit([np.array([[0.0, 10.0], [2.0, 30.0]])])
    >>> s.offset_, s.scale_
    (array([ 1., 20.]), array([ 1., 10.]))
    >>> s.transform(np.array([[3.0, 20.0]]))
    array([[2., 0.]])
    """

    @classmethod
    def fitted(cls, offset, scale) -> ChannelScaling:
        """A scaling with given ``offset_`` and ``scale_`` (one positive scale per channel)."""
        scaling = cls()
        scaling.offset_ = np.asarray(offset, dtype=float).reshape(-1)
        scaling.scale_ = np.asarray(scale, dtype=float).reshape(-1)
        if scaling.offset_.shape != scaling.scale_.shape or not (scaling.scale_ > 0).all():
            raise ValueError("channel scaling needs one offset and one positive scale per channel")
        return scaling

    def fit(self, sequences: list[np.ndarray], y=None) -> ChannelScaling:
        """Learn ``offset_`` and ``scale_`` from (T, d) training ``sequences``; returns self."""
        Y = np.vstack([np.asarray(s, dtype=float) for s in sequences])
        if not np.isfinite(Y).all():
            raise ValueError("training data hold NaN/inf; repair them before training")
        self.offset_ = Y.mean(axis=0)
        std = Y.std(axis=0)
        self.scale_ = np.where(std > MIN_SCALE, std, 1.0)
        return self

    def transform(self, Y: np.ndarray) -> np.ndarray:
        """Observations (..., d) scaled per channel."""
        check_is_fitted(self, "offset_")
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
        check_is_fitted(self, "offset_")
        return self.offset_ + self.scale_ * np.asarray(Z, dtype=float)

    def to_provenance(self) -> dict:
        return {"channel_offset": self.offset_.tolist(), "channel_scale": self.scale_.tolist()}

    @classmethod
    def from_model(cls, model) -> ChannelScaling | None:
        """The scaling stored with a trained model, or None (models trained on raw channels)."""
        prov = getattr(model, "provenance_", None) or {}
        if "channel_scale" not in prov:
            return None
        return cls.fitted(prov["channel_offset"], prov["channel_scale"])

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
