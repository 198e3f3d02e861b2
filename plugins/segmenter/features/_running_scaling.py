"""Causal per-recording standardisation with the training frames as the prior (docs/segmentation.md,
"Per-recording normalisation").

Recordings of different people differ in position: z-scored with the training frames' statistics
(:class:`._scaling.ChannelScaling`) each keeps its own offset.  :class:`RunningStandardizer`
standardises frame t of a recording with the mean and variance of ``prior_frames`` pseudo-frames at
the training statistics pooled with the recording's own frames 0…t.  It is causal, so a stream
standardised sample by sample (:meth:`RunningStandardizer.stream`) equals the whole recording
standardised at once.
"""

from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted

from ._scaling import ChannelScaling


def _frames(X, what: str, n_channels: int | None = None, single: bool = False) -> np.ndarray:
    """X as a finite float (frames, channels) array — one frame when ``single`` — or a ValueError
    that says what is wrong."""
    try:
        X = np.asarray(X, dtype=float).reshape(1, -1) if single else np.asarray(X, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:  # OverflowError: a huge integer
        raise ValueError(f"{what}: not numeric ({exc})") from None
    if X.ndim != 2 or X.shape[1] == 0:
        raise ValueError(f"{what}: expected a (frames, channels) array, got shape {X.shape}")
    if n_channels is not None and X.shape[1] != n_channels:
        raise ValueError(f"{what}: {X.shape[1]} channels, but the prior has {n_channels}")
    if not np.isfinite(X).all():
        raise ValueError(f"{what}: NaN/inf values; drop or repair them first")
    return X


class RunningStandardizer(BaseEstimator):
    """Standardises a recording causally: frame t with the statistics of the prior and frames 0…t.

    The prior is ``prior_frames`` (n0) pseudo-frames at the per-channel mean ``mean_`` and standard
    deviation ``scale_`` of the training frames (:meth:`fit`, or :meth:`set_prior` with a stored
    scaling).  Frame t has the pooled mean ``m_t`` and variance ``v_t`` of n0 + t + 1 frames and
    becomes ``(x_t − m_t) / sqrt(max(v_t, variance_floor · scale_²))``.

    Documented choices (docs/segmentation.md): ``prior_frames=200`` — the recording's own statistics
    weigh half after 200 frames (≈ 7 s of the 30 Hz gesture-phase recordings), so its first seconds,
    often a single rest or motion, do not set the normalisation alone, and 84 % at the end of the
    shortest of those recordings (1073 frames); ``variance_floor=0.01`` — a channel that stops
    moving is amplified at most 10× beyond the training scaling.  The sums are accumulated in prior
    units (``(x − mean_) / scale_``), so the variance ``E[u²] − m²`` cancels no large offset.

    Parameters
    ----------
    prior_frames : float, default 200
        n0, pseudo-frames of the prior.
    variance_floor : float, default 0.01
        Smallest variance, as a share of the prior's ``scale_²``.

    Attributes
    ----------
    mean_, scale_ : ndarray of shape (n_channels,)
        The prior: per-channel mean and standard deviation of the training frames.
    n_features_in_ : int
        Channels.

    Examples
    --------
    >>> import numpy as np
    >>> from handflow.plugins.segmenter.features import RunningStandardizer
    >>> scaler = RunningStandardizer(prior_frames=1).fit(np.array([[0.0], [2.0]]))
    >>> scaler.mean_, scaler.scale_
    (array([1.]), array([1.]))
    >>> scaler.transform(np.array([[1.0], [3.0]]))
    array([[0.        ],
           [1.20604538]])
    """

    def __init__(self, *, prior_frames: float = 200, variance_floor: float = 0.01) -> None:
        self.prior_frames = prior_frames
        self.variance_floor = variance_floor

    def fit(self, X, y=None) -> RunningStandardizer:
        """Learn the prior from training frames X (frames, channels)."""
        X = _frames(X, "training frames")
        if len(X) == 0:
            raise ValueError("training frames: none given; the prior needs at least one frame")
        prior = ChannelScaling().fit([X])
        return self.set_prior(prior.offset_, prior.scale_)

    def set_prior(self, mean, scale) -> RunningStandardizer:
        """Use a stored prior (e.g. the channel scaling saved with class models, :mod:`._scaling`)."""
        for name in ("prior_frames", "variance_floor"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float, np.number)) and np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        prior = ChannelScaling.fitted(mean, scale)
        if not np.isfinite(prior.offset_).all() or not np.isfinite(prior.scale_).all():
            raise ValueError("the prior mean and scale must be finite")
        self.mean_, self.scale_ = prior.offset_, prior.scale_
        self.n_features_in_ = self.mean_.size
        return self

    def transform(self, X) -> np.ndarray:
        """One recording X (frames, channels), standardised causally (vectorised by cumulative sums)."""
        check_is_fitted(self, "mean_")
        U = self._prior_units(_frames(X, "frames", self.n_features_in_))
        with np.errstate(over="ignore", invalid="ignore"):
            s1, s2 = np.cumsum(U, axis=0), np.cumsum(U * U, axis=0)
        return self._standardised(U, s1, s2, self.prior_frames + np.arange(1.0, len(U) + 1)[:, None])

    def stream(self) -> RunningStream:
        """A frame-by-frame standardiser equal to :meth:`transform` of the whole recording."""
        check_is_fitted(self, "mean_")
        return RunningStream(self)

    def _prior_units(self, X: np.ndarray) -> np.ndarray:
        return (X - self.mean_) / self.scale_

    def _standardised(self, U: np.ndarray, s1: np.ndarray, s2: np.ndarray, n) -> np.ndarray:
        """Frames U in prior units (prior mean 0, variance 1) standardised with the n frames pooled
        from the prior and the recording's sums ``s1`` = Σu, ``s2`` = Σu² (n − n0 frames)."""
        with np.errstate(over="ignore", invalid="ignore"):
            mean = s1 / n
            var = (self.prior_frames + s2) / n - mean * mean
        if not np.isfinite(var).all():
            raise ValueError("frames lie too far from the prior mean (beyond ~1e150 of its scale) to standardise")
        return (U - mean) / np.sqrt(np.maximum(var, self.variance_floor))


class RunningStream:
    """Standardises one frame at a time (see :meth:`RunningStandardizer.stream`)."""

    def __init__(self, scaler: RunningStandardizer) -> None:
        self.scaler = scaler
        self.count = 0
        self._s1 = np.zeros(scaler.n_features_in_)
        self._s2 = np.zeros(scaler.n_features_in_)

    def push(self, x) -> np.ndarray:
        """The standardised frame (channels,) of the newest frame x; a bad frame raises ValueError
        and leaves the stream as it was."""
        u = self.scaler._prior_units(_frames(x, "frame", self.scaler.n_features_in_, single=True))[0]
        with np.errstate(over="ignore", invalid="ignore"):
            s1, s2 = self._s1 + u, self._s2 + u * u
        z = self.scaler._standardised(u, s1, s2, self.scaler.prior_frames + (self.count + 1.0))
        self._s1, self._s2, self.count = s1, s2, self.count + 1
        return z

    def update(self, x) -> np.ndarray:
        """:meth:`push` (its name before the streaming contract, docs/segmentation.md)."""
        return self.push(x)
