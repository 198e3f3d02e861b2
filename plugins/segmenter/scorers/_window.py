"""Fitted frame scorers, saved without pickle (docs/segmentation.md, "Score sources").

A scorer gives every frame of a stream per-class scores (larger = more likely) from the causal
window of the last ``window`` frames: :class:`MiniRocketScorer` (MiniRocket features + a ridge
classifier, aeon) and :class:`DTWScorer` (sliding-window subsequence DTW 1-NN).  They are the
score sources of the CLM segmentation layer (:mod:`..online`).  Every scorer fixes its
evidence temperature (:func:`..compatibility.evidence_temperature`) on its training frames, so
the online node maps scores to evidence the same way on every sample.

File format (:meth:`WindowScorer.save`, :func:`load_scorer`): one ``.npz`` of plain numeric
arrays plus ``metadata``, a JSON string with the format name and version, the scorer kind, its
hyper-parameters, class names, temperature and the SHA-256 of every array.  Loading never
unpickles, checks the version (a file of another version is refused with what to do) and the
checksums (a truncated or edited file is refused), then the arrays' shapes.
"""

from __future__ import annotations

import hashlib
import json
from abc import ABC, abstractmethod
from pathlib import Path
from typing import ClassVar

import numpy as np
from sklearn.base import BaseEstimator

from handflow.framework.npz_files import NpzFileError, building, npz_metadata, read_npz

from ..compatibility import evidence_temperature, score_evidence
from ..novelty import FeatureNovelty
from ._baselines import SlidingDTW1NN

FORMAT = "handflow.scorer"
FORMAT_VERSION = 2  # 2: MiniRocket scorers keep their feature novelty
WINDOWS_PER_SEGMENT = 12  # MiniRocket training windows per segment


class ScorerFileError(NpzFileError):
    """A scorer file that cannot be used; the message says what to change."""


def causal_windows(X: np.ndarray, ends: np.ndarray, width: int) -> np.ndarray:
    """(len(ends), channels, width) causal windows ending at ``ends``; the first frame pads the start."""
    idx = np.clip(ends[:, None] - np.arange(width - 1, -1, -1)[None], 0, None)
    return np.ascontiguousarray(X[idx].transpose(0, 2, 1))


class WindowScorer(BaseEstimator, ABC):
    """Per-class scores of the causal window ending at each frame; fitted on segments per class.

    After :meth:`fit`: ``classes_`` (class names, score column order), ``n_features_in_`` and
    ``temperature_`` (the evidence temperature of :meth:`evidence`).
    """

    kind: ClassVar[str] = ""
    has_features: ClassVar[bool] = False  # whether :meth:`scores_and_novelty` gives a feature novelty

    def fit(self, segments: dict) -> WindowScorer:
        """Fit on ``{class: [segment (T, D), ...]}``; returns self."""
        if not segments or any(not segs for segs in segments.values()):
            raise ValueError("need at least one training segment for every class")
        dims = {s.shape[1] for segs in segments.values() for s in segs}
        if len(dims) != 1:
            raise ValueError(f"training segments differ in their number of channels: {sorted(dims)}")
        if int(self.window) < 1:
            raise ValueError(f"window must be >= 1 frame, got {self.window}")
        self.classes_ = list(segments)
        self.n_features_in_ = dims.pop()
        self.temperature_ = evidence_temperature(self._fit(segments))
        return self

    @abstractmethod
    def _fit(self, segments: dict) -> np.ndarray:
        """Fit the model; returns class scores of training frames, for the evidence temperature."""

    @abstractmethod
    def scores(self, X: np.ndarray) -> np.ndarray:
        """(N, M) class scores of every frame of a recording X (N, D)."""

    def scores_last(self, recent: np.ndarray) -> np.ndarray:
        """(M,) class scores of the last frame of ``recent`` (the stream's last ``window`` frames,
        fewer at its start) — the same as :meth:`scores` of the whole stream at that frame."""
        return self.scores(np.asarray(recent, dtype=float)[-int(self.window) :])[-1]

    def scores_and_novelty(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`scores` and the frames' feature novelty (N,) (:mod:`..novelty`; None
        for a scorer without features)."""
        return self.scores(X), None

    def scores_and_novelty_last(self, recent: np.ndarray) -> tuple[np.ndarray, float | None]:
        """:meth:`scores_last` and the last frame's feature novelty (None without features)."""
        return self.scores_last(recent), None

    def evidence(self, scores: np.ndarray) -> np.ndarray:
        """Scores → class evidence in [0, 1] at the fitted temperature."""
        return score_evidence(np.atleast_2d(scores), self.temperature_)

    def check_input(self, X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if X.shape[1] != self.n_features_in_:
            raise ValueError(f"observations must have {self.n_features_in_} channels, got {X.shape[1]}")
        if not np.isfinite(X).all():
            raise ValueError("observations hold NaN/inf")
        return X

    # -- persistence -------------------------------------------------------------------------
    @abstractmethod
    def _arrays(self) -> dict[str, np.ndarray]:
        """The fitted state as named arrays."""

    @abstractmethod
    def _restore(self, arrays: dict[str, np.ndarray]) -> None:
        """Set the fitted state from :meth:`_arrays`' output (shapes checked; raises ValueError)."""

    def save(self, path: str | Path) -> Path:
        """Write the fitted scorer to ``path`` (.npz of arrays + JSON metadata, no pickle)."""
        arrays = {k: np.ascontiguousarray(v) for k, v in self._arrays().items()}
        meta = {
            "format": FORMAT,
            "version": FORMAT_VERSION,
            "kind": self.kind,
            "params": self.get_params(),
            "classes": [str(c) for c in self.classes_],
            "n_features_in": int(self.n_features_in_),
            "temperature": float(self.temperature_),
            "sha256": {k: _digest(v) for k, v in arrays.items()},
        }
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("wb") as f:
            np.savez(f, metadata=np.array(json.dumps(meta)), **arrays)
        return path


def _digest(a: np.ndarray) -> str:
    h = hashlib.sha256(f"{a.dtype.str}{a.shape}".encode())
    h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


class MiniRocketScorer(WindowScorer):
    """MiniRocket features (aeon) of the causal window + a ridge classifier (cross-validated α).

    The input is standardised with the training frames' mean and std (``mean_``, ``std_``).
    Training windows end at up to ``WINDOWS_PER_SEGMENT`` evenly spaced frames of each segment
    (a window reaching before a segment's start repeats its first frame; documented choice that
    keeps the ridge fit affordable).  Scores are the ridge decision values, one column per class
    (two for a binary problem); the evidence temperature comes from those of the training windows.  Fitted: ``parameters_`` (the MiniRocket transform: channels per
    combination, channel indices, dilations, features per dilation, biases), ``coef_`` (M, F),
    ``intercept_`` (M,), ``novelty_`` (:class:`..novelty.FeatureNovelty` of the training
    windows' features; None with ``feature_novelty=False``, which skips its fit — a third of the
    fit's time — for users of the scores alone; such a scorer cannot be saved).
    """

    kind = "minirocket"
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
        for k, segs in enumerate(segments.values()):
            for seg in segs:
                ends = np.unique(np.linspace(0, len(seg) - 1, WINDOWS_PER_SEGMENT).astype(int))
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


class DTWScorer(WindowScorer):
    """Sliding-window subsequence DTW 1-NN (:class:`._baselines.SlidingDTW1NN`): score of class c =
    − the smallest length-normalised DTW cost of the window inside one of c's training segments.
    References are thinned to every ``thin``-th frame when at least 8 of them remain."""

    kind = "dtw"

    def __init__(self, *, window: int = 20, thin: int = 4) -> None:
        self.window = window
        self.thin = thin

    def _fit(self, segments: dict) -> None:
        k = int(self.thin)
        refs = {c: [s[::k] if len(s) >= 8 * k else s for s in segs] for c, segs in segments.items()}
        self.model_ = SlidingDTW1NN(window=int(self.window)).fit(refs)
        return np.vstack([self.model_.scores(s) for segs in segments.values() for s in segs])

    def scores(self, X: np.ndarray) -> np.ndarray:
        return self.model_.scores(self.check_input(X))

    def _arrays(self) -> dict[str, np.ndarray]:
        m = self.model_
        return {"mean": m.mean_, "std": m.std_, "refs": m.refs_, "offsets": m.offsets_, "owner": m.owner_}

    def _restore(self, arrays: dict[str, np.ndarray]) -> None:
        d, m = self.n_features_in_, len(self.classes_)
        refs, offsets, owner = arrays["refs"], arrays["offsets"], arrays["owner"]
        if (
            arrays["mean"].shape != (d,)
            or arrays["std"].shape != (d,)
            or (arrays["std"] <= 0).any()
            or refs.ndim != 2
            or refs.shape[1] != d
            or refs.dtype.kind != "f"
            or offsets.ndim != 1
            or offsets.dtype.kind != "i"
            or offsets.size != owner.size + 1
            or offsets[0] != 0
            or offsets[-1] != len(refs)
            or (np.diff(offsets) < 1).any()
            or owner.dtype.kind != "i"
            or set(owner.tolist()) != set(range(m))
        ):
            raise ValueError("DTW references are inconsistent with each other or with the input channels")
        model = SlidingDTW1NN(window=int(self.window))
        model.classes_, model.mean_, model.std_ = list(self.classes_), arrays["mean"], arrays["std"]
        model.refs_, model.offsets_, model.owner_ = np.ascontiguousarray(refs), offsets.astype(np.int64), owner
        self.model_ = model


SCORERS: dict[str, type[WindowScorer]] = {"minirocket": MiniRocketScorer, "dtw": DTWScorer}


def load_scorer(path: str | Path) -> WindowScorer:
    """Read a scorer written by :meth:`WindowScorer.save`; :class:`ScorerFileError` on any bad file."""
    path = Path(path)
    refit = "fit a new one with `handflow fit-scorer` (docs/segmentation.md)"
    arrays = read_npz(path, "scorer", refit, ScorerFileError)
    meta = _metadata(path, arrays, refit)
    arrays.pop("metadata")
    cls = SCORERS[meta["kind"]]
    for name, digest in meta["sha256"].items():
        if name not in arrays or _digest(arrays[name]) != digest:
            raise ScorerFileError(f"{path}: array '{name}' is missing or changed since it was saved; {refit}")
    if set(arrays) != set(meta["sha256"]):
        raise ScorerFileError(f"{path}: unexpected arrays {sorted(set(arrays) - set(meta['sha256']))}; {refit}")
    with building(path, f"{meta['kind']} scorer", refit, ScorerFileError):
        scorer = cls(**meta["params"])
        scorer.classes_ = list(meta["classes"])
        scorer.n_features_in_ = int(meta["n_features_in"])
        scorer.temperature_ = float(meta["temperature"])
        if not (scorer.classes_ and scorer.n_features_in_ >= 1 and scorer.temperature_ > 0 and int(scorer.window) >= 1):
            raise ValueError("classes, channels, temperature or window out of range")
        scorer._restore(arrays)
    return scorer


def _metadata(path: Path, arrays: dict, refit: str) -> dict:
    meta = npz_metadata(arrays, path, "scorer", refit, ScorerFileError, (FORMAT, FORMAT_VERSION, "version"))
    kinds = {"kind": str, "params": dict, "classes": list, "sha256": dict}
    if any(not isinstance(meta.get(k), t) for k, t in kinds.items()) or meta["kind"] not in SCORERS:
        raise ScorerFileError(f"{path}: scorer metadata lacks or garbles kind/params/classes/sha256; {refit}")
    if not all(isinstance(v, str) for v in meta["sha256"].values()):
        raise ScorerFileError(f"{path}: scorer metadata garbles the checksums; {refit}")
    return meta
