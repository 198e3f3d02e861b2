"""Fitted frame scorers, saved without pickle (docs/segmentation.md, "Score sources").

A scorer gives every frame of a stream per-class scores (larger = more likely) from the causal
window of the last ``window`` frames: :class:`MiniRocketScorer` (MiniRocket features + a ridge
classifier, aeon) and :class:`DTWScorer` (sliding-window subsequence DTW 1-NN).  They are the
score sources of the CLM segmentation layer (:mod:`..online`).  Every scorer fixes its
evidence temperature (:func:`..compatibility.evidence_temperature`) on its training frames, so
the online node maps scores to evidence the same way on every sample.

File format (:meth:`WindowScorer.save`, :func:`load_scorer`): one ``.npz`` of plain numeric
arrays plus ``metadata``, a JSON string with the format name and version, the scorer kind, its
hyper-parameters, class names, temperature, the SHA-256 of every array and, once calibrated by
``fit-scorer``, the null class's score (``null_score``, −inf = rejection off) with its report
(``null_calibration``; files without them load with ``null_score_`` None).  Loading never
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
from sklearn.utils.validation import check_is_fitted

from handflow.framework.files.npz import NpzFileError

from ..compatibility import evidence_temperature, score_evidence

FORMAT = "handflow.scorer"
FORMAT_VERSION = 2  # 2: MiniRocket scorers keep their feature novelty


class ScorerFileError(NpzFileError):
    """A scorer file that cannot be used; the message says what to change."""


def causal_windows(X: np.ndarray, ends: np.ndarray, width: int) -> np.ndarray:
    """(len(ends), channels, width) causal windows ending at ``ends``; the first frame pads the start."""
    idx = np.clip(ends[:, None] - np.arange(width - 1, -1, -1)[None], 0, None)
    return np.ascontiguousarray(X[idx].transpose(0, 2, 1))


class WindowScorer(BaseEstimator, ABC):
    """Per-class scores of the causal window ending at each frame; fitted on segments per class.

    After :meth:`fit`: ``classes_`` (class names, score column order), ``n_features_in_``,
    ``temperature_`` (the evidence temperature of :meth:`evidence`) and ``null_score_``, the null
    class's score on the scorer's scale that ``fit-scorer`` calibrates (None until then; its report
    in ``null_calibration_``; docs/segmentation.md, "Score sources").
    """

    kind: ClassVar[str] = ""
    has_features: ClassVar[bool] = False  # whether :meth:`scores_and_novelty` gives a feature novelty
    requires: ClassVar[dict[str, str]] = {}  # modules beyond the core → the extra that installs them

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
        self.null_score_, self.null_calibration_ = None, None
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
        """X as a finite (N, n_features_in_) array; ``NotFittedError`` before :meth:`fit`."""
        check_is_fitted(self, "temperature_")
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
        if self.null_score_ is not None:
            meta.update(null_score=float(self.null_score_), null_calibration=self.null_calibration_)
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("wb") as f:
            np.savez(f, metadata=np.array(json.dumps(meta)), **arrays)
        return path


def _digest(a: np.ndarray) -> str:
    h = hashlib.sha256(f"{a.dtype.str}{a.shape}".encode())
    h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()
