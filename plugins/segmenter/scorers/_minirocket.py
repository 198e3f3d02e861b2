"""MiniRocket frame scorer (aeon): features of the causal window + a ridge classifier, with the
feature novelty of its training windows (docs/segmentation.md, "Score sources")."""

from __future__ import annotations

import numpy as np

from ..novelty import FeatureNovelty
from ._window import WindowScorer, causal_windows

WINDOWS_PER_SEGMENT = 12  # MiniRocket training windows per segment
MAX_TRAINING_WINDOWS = 2000  # fewer windows per segment (one at least) beyond this many in all


class MiniRocketScorer(WindowScorer):
    """MiniRocket features (aeon) of the causal window + a ridge classifier (cross-validated α).

    The input is standardised with the training frames' mean and std (``mean_``, ``std_``).
    Training windows end at up to ``WINDOWS_PER_SEGMENT`` evenly spaced frames of each segment
    (a window reaching before a segment's start repeats its first frame), fewer per segment when
    that would exceed ``MAX_TRAINING_WINDOWS`` in all (documented choice that keeps the ridge fit
    affordable — its cross-validation costs the cube of the windows — and the cost linear in the
    recordings' length; docs/segmentation.md, "Score sources").  Scores are the ridge decision values, one column per class
    (two for a binary problem); the evidence temperature comes from those of the training windows.  Fitted: ``parameters_`` (the MiniRocket transform: channels per
    combination, channel indices, dilations, features per dilation, biases), ``coef_`` (M, F),
    ``intercept_`` (M,), ``novelty_`` (:class:`..novelty.FeatureNovelty` of the training
    windows' features; None with ``feature_novelty=False``, which skips its fit — a third of the
    fit's time — for users of the scores alone; such a scorer cannot be saved).

    Parameters
    ----------
    window : int, default 32
        Frames of the causal window.
    n_kernels : int, default 10000
        MiniRocket features (rounded down to a multiple of 84 by aeon).
    random_state : int or None, default 0
        Seed of the MiniRocket biases.
    feature_novelty : bool, default True
        Fit the feature novelty of the training windows.

    Attributes
    ----------
    classes_ : list of str
        Class names, the score columns' order.
    n_features_in_ : int
        Channels of the training segments.
    temperature_ : float
        Evidence temperature of :meth:`evidence`.
    mean_, std_ : ndarray of shape (d,)
        Standardisation of the training frames.
    parameters_, coef_, intercept_, novelty_
        The MiniRocket transform, the ridge classifier and the feature novelty (above).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 4 * np.pi, 40)
    >>> train = {"circle": [np.c_[np.sin(t), np.cos(t)]], "line": [np.c_[t, t]]}
    >>> from handflow.plugins.segmenter.scorers import MiniRocketScorer
    >>> scorer = MiniRocketScorer(window=12, n_kernels=84).fit(train)
    >>> scorer.scores(train["circle"][0]).shape
    (40, 2)
    """

    kind = "minirocket"
    requires = {"aeon": "minirocket"}
    PARAMETER_NAMES = ("n_channels_per_combination", "channel_indices", "dilations", "features_per_dilation", "biases")

    def __init__(
        self, *, window: int = 32, n_kernels: int = 10_000, random_state: int | None = 0, feature_novelty: bool = True
    ) -> None:
        self.window = window
        self.n_kernels = n_kernels
        self.random_state = random_state
        self.feature_novelty = feature_novelty

    @property
    def has_features(self) -> bool:
        return bool(self.feature_novelty)

    def _fit(self, segments: dict) -> None:
        MiniRocket, _ = _aeon()
        from sklearn.linear_model import RidgeClassifierCV

        if int(self.window) < 9:
            raise ValueError(f"MiniRocket needs a window of at least 9 frames, got {self.window}")
        if len(segments) < 2:
            raise ValueError("a MiniRocket scorer needs at least 2 classes")
        frames = np.vstack([s for segs in segments.values() for s in segs])
        self.mean_ = frames.mean(axis=0)
        sd = frames.std(axis=0)
        self.std_ = np.where(sd > 0, sd, 1.0)
        windows, targets, origins = [], [], []
        per_segment = min(WINDOWS_PER_SEGMENT, max(1, MAX_TRAINING_WINDOWS // sum(map(len, segments.values()))))
        for k, segs in enumerate(segments.values()):
            for seg in segs:
                ends = np.unique(np.linspace(0, len(seg) - 1, per_segment).astype(int))
                windows.append(causal_windows((seg - self.mean_) / self.std_, ends, int(self.window)))
                targets.append(np.full(len(ends), k))
                origins.append(np.full(len(ends), len(origins)))
        transform = MiniRocket(n_kernels=self.n_kernels, random_state=self.random_state).fit(np.concatenate(windows))
        self.parameters_ = tuple(np.asarray(p) for p in transform.parameters)
        F = self.features(np.concatenate(windows))
        ridge = RidgeClassifierCV(alphas=np.logspace(-3, 3, 10)).fit(F, np.concatenate(targets))
        coef, intercept = np.atleast_2d(ridge.coef_), np.atleast_1d(ridge.intercept_)  # (F,) when binary
        if coef.shape[0] == 1:  # binary: one decision value d, scores (−d, d)
            coef, intercept = np.vstack([-coef, coef]), np.r_[-intercept, intercept]
        self.coef_, self.intercept_ = coef, intercept
        self.novelty_ = FeatureNovelty.fit(F, np.concatenate(origins)) if self.feature_novelty else None
        return F @ coef.T + intercept

    def features(self, windows: np.ndarray) -> np.ndarray:
        """MiniRocket features (n, F) of standardised windows (n, channels, window)."""
        _, kernels = _aeon()
        X = np.ascontiguousarray(windows, dtype=np.float32)
        if X.shape[1] == 1:
            return kernels.uni(X[:, 0], self.parameters_, kernels.indices)
        return kernels.multi(X, self.parameters_, kernels.indices)

    def window_features(self, X: np.ndarray, ends: np.ndarray | None = None) -> np.ndarray:
        """Features (n, F) of the causal windows ending at ``ends`` (default: every frame of X)."""
        Z = (self.check_input(X) - self.mean_) / self.std_
        ends = np.arange(len(Z)) if ends is None else np.asarray(ends, dtype=int)
        return self.features(causal_windows(Z, ends, int(self.window))).astype(float)

    def scores(self, X: np.ndarray, ends: np.ndarray | None = None) -> np.ndarray:
        """Class scores of the causal windows ending at ``ends`` (default: every frame of X)."""
        return self.window_features(X, ends) @ self.coef_.T + self.intercept_

    def scores_last(self, recent: np.ndarray) -> np.ndarray:
        recent = np.atleast_2d(np.asarray(recent, dtype=float))[-int(self.window) :]
        return self.scores(recent, ends=[len(recent) - 1])[0]

    def scores_and_novelty(self, X: np.ndarray, ends: np.ndarray | None = None):
        F = self.window_features(X, ends)
        return F @ self.coef_.T + self.intercept_, self._novelty().novelty(F)

    def scores_and_novelty_last(self, recent: np.ndarray):
        recent = np.atleast_2d(np.asarray(recent, dtype=float))[-int(self.window) :]
        scores, novelty = self.scores_and_novelty(recent, ends=[len(recent) - 1])
        return scores[0], float(novelty[0])

    def _arrays(self) -> dict[str, np.ndarray]:
        return {
            "mean": self.mean_,
            "std": self.std_,
            "coef": self.coef_,
            "intercept": self.intercept_,
            **dict(zip(self.PARAMETER_NAMES, self.parameters_)),
            **self._novelty().arrays("novelty_"),
        }

    def _novelty(self) -> FeatureNovelty:
        if self.novelty_ is None:
            raise ValueError("this scorer was fitted with feature_novelty=False; fit it with feature_novelty=True")
        return self.novelty_

    def _restore(self, arrays: dict[str, np.ndarray]) -> None:
        d, m = self.n_features_in_, len(self.classes_)
        names = self.PARAMETER_NAMES
        params = tuple(arrays[k] for k in names)
        n_comb, channels, dilations, per_dilation, biases = params
        n_feat = biases.size
        expected = {"mean": (d,), "std": (d,), "coef": (m, n_feat), "intercept": (m,)}
        for k, shape in expected.items():
            if arrays[k].shape != shape or arrays[k].dtype.kind != "f":
                raise ValueError(
                    f"'{k}' must be a float array of shape {shape}, got {arrays[k].dtype} {arrays[k].shape}"
                )
        if any(p.ndim != 1 for p in params) or [p.dtype.kind for p in params] != ["i", "i", "i", "i", "f"]:
            raise ValueError("MiniRocket parameters must be four 1-D integer arrays and 1-D float biases")
        if (
            n_comb.sum() != channels.size
            or (channels < 0).any()
            or (channels >= d).any()
            or (dilations < 1).any()
            or dilations.size != per_dilation.size
            or (per_dilation < 0).any()
            or 84 * per_dilation.sum() != n_feat
            or n_comb.size != 84 * dilations.size
            or not np.isfinite(biases).all()
            or (arrays["std"] <= 0).any()
        ):
            raise ValueError("MiniRocket parameters are inconsistent with each other or with the input channels")
        self.novelty_ = FeatureNovelty.from_arrays(arrays, "novelty_", n_feat)
        self.mean_, self.std_ = arrays["mean"], arrays["std"]
        self.coef_, self.intercept_ = arrays["coef"], arrays["intercept"]
        self.parameters_ = tuple(np.ascontiguousarray(p, dtype=np.float32 if p is biases else np.int32) for p in params)


class _Kernels:
    """aeon's compiled MiniRocket transforms (the transform of a fitted ``MiniRocket``)."""

    def __init__(self) -> None:
        from aeon.transformations.collection.convolution_based import _minirocket as mr

        self.uni, self.multi, self.indices = (
            mr._static_transform_uni,
            mr._static_transform_multi,
            mr.MiniRocket._indices,
        )


def _aeon():
    try:
        from aeon.transformations.collection.convolution_based import MiniRocket
    except ImportError:
        raise ImportError(
            "the MiniRocket scorer needs aeon: pip install 'handflow[minirocket]' (or use another source)"
        ) from None
    return MiniRocket, _Kernels()
