"""Sliding-window subsequence DTW (docs/segmentation.md): the compiled kernel, shared by the 1-NN
baseline (:class:`SlidingDTW1NN`) and the saved frame scorer (:class:`DTWScorer`)."""

from __future__ import annotations

import numba
import numpy as np
from sklearn.utils.validation import check_is_fitted

from ..models import thin_pieces
from ._scores import _check_window, _Standardiser, decide
from ._window import WindowScorer

MAX_REFERENCE_FRAMES = 2000  # thinned reference frames per class (documented choice, docs/segmentation.md)


def dtw_references(
    segments: list[np.ndarray], thin: int = 4, max_frames: int = MAX_REFERENCE_FRAMES
) -> list[np.ndarray]:
    """A class's references: every ``thin``-th frame of a segment where at least 8 remain, and
    beyond ``max_frames`` of those, evenly spaced whole segments (:func:`..models.thin_pieces`;
    documented choice: labelling then costs time linear in the recording, however much trains)."""
    k = int(thin)
    return thin_pieces([s[::k] if len(s) >= 8 * k else s for s in segments], int(max_frames))


@numba.njit(cache=True)
def _subsequence_dtw(Q, R):  # pragma: no cover - compiled
    """Open-begin/open-end DTW of query Q (w, d) inside reference R (n, d): min accumulated cost."""
    w, n = Q.shape[0], R.shape[0]
    prev = np.empty(n)
    cur = np.empty(n)
    for j in range(n):
        c = 0.0
        for k in range(Q.shape[1]):
            diff = Q[0, k] - R[j, k]
            c += diff * diff
        prev[j] = np.sqrt(c)
    for i in range(1, w):
        for j in range(n):
            c = 0.0
            for k in range(Q.shape[1]):
                diff = Q[i, k] - R[j, k]
                c += diff * diff
            best = prev[j]
            if j > 0:
                if cur[j - 1] < best:
                    best = cur[j - 1]
                if prev[j - 1] < best:
                    best = prev[j - 1]
            cur[j] = np.sqrt(c) + best
        prev, cur = cur, prev
    return prev.min()


@numba.njit(cache=True)
def _sliding_dtw(Y, refs, offsets, window):  # pragma: no cover - compiled
    """Distance (N, n_refs) of each causal window of Y to each reference, per query point."""
    N = Y.shape[0]
    out = np.empty((N, offsets.shape[0] - 1))
    for t in range(N):
        lo = max(0, t - window + 1)
        Q = Y[lo : t + 1]
        for r in range(offsets.shape[0] - 1):
            out[t, r] = _subsequence_dtw(Q, refs[offsets[r] : offsets[r + 1]]) / Q.shape[0]
    return out


class SlidingDTW1NN(_Standardiser):
    """1-nearest-neighbour over training sequences with open-begin/end subsequence DTW.

    Score of class c at ``t`` = − min over c's training sequences of the DTW cost of the window
    ``y_{t−w+1…t}`` divided by its length.  ``threshold`` (on that score) rejects.

    Parameters
    ----------
    window : int, default 10
        w, frames of the causal window.
    threshold : float or None, default None
        Frames whose best score is below it are rejected (−1) by :meth:`predict`.

    Attributes
    ----------
    classes_ : list of str
        Class names, the score columns' order.
    mean_, std_ : ndarray of shape (d,)
        Standardisation of the training frames.
    refs_ : ndarray of shape (n_frames, d)
        The standardised training sequences, one after another.
    offsets_ : ndarray of shape (n_sequences + 1,)
        Where each training sequence starts in ``refs_``.
    owner_ : ndarray of shape (n_sequences,)
        Class index of each training sequence.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 4 * np.pi, 40)
    >>> train = {"circle": [np.c_[np.sin(t), np.cos(t)]], "line": [np.c_[t, t]]}
    >>> from handflow.plugins.segmenter.scorers import SlidingDTW1NN
    >>> SlidingDTW1NN(window=5).fit(train).predict(train["line"][0][:8]).tolist()
    [1, 1, 1, 1, 1, 1, 1, 1]
    """

    def __init__(self, *, window: int = 10, threshold: float | None = None) -> None:
        self.window = window
        self.threshold = threshold

    def fit(self, sequences_by_class: dict[str, list[np.ndarray]]) -> SlidingDTW1NN:
        _check_window(self.window)
        if not sequences_by_class:
            raise ValueError("need at least one class with training sequences")
        self.classes_ = list(sequences_by_class)
        self.fit_from([s for seqs in sequences_by_class.values() for s in seqs])
        refs, owner = [], []
        for c, seqs in enumerate(sequences_by_class.values()):
            refs += [self.standardise(s) for s in seqs]
            owner += [c] * len(seqs)
        self.refs_ = np.ascontiguousarray(np.vstack(refs))
        self.offsets_ = np.r_[0, np.cumsum([len(r) for r in refs])].astype(np.int64)
        self.owner_ = np.asarray(owner)
        return self

    def scores(self, Y: np.ndarray) -> np.ndarray:
        """(N, M) class scores."""
        check_is_fitted(self, "refs_")
        _check_window(self.window)
        d = _sliding_dtw(np.ascontiguousarray(self.standardise(Y)), self.refs_, self.offsets_, int(self.window))
        out = np.full((d.shape[0], len(self.classes_)), -np.inf)
        for c in range(len(self.classes_)):
            out[:, c] = -d[:, self.owner_ == c].min(axis=1)
        return out

    def predict(self, Y: np.ndarray) -> np.ndarray:
        return decide(self.scores(Y), self.threshold)


class DTWScorer(WindowScorer):
    """Sliding-window subsequence DTW 1-NN (:class:`SlidingDTW1NN`): score of class c =
    − the smallest length-normalised DTW cost of the window inside one of c's training segments.
    References are thinned to every ``thin``-th frame when at least 8 of them remain, and to at
    most :data:`MAX_REFERENCE_FRAMES` thinned frames per class (:func:`dtw_references`).

    Parameters
    ----------
    window : int, default 20
        Frames of the causal window.
    thin : int, default 4
        Keep every ``thin``-th frame of a training segment as reference.

    Attributes
    ----------
    classes_ : list of str
        Class names, the score columns' order.
    n_features_in_ : int
        Channels of the training segments.
    temperature_ : float
        Evidence temperature of :meth:`evidence`.
    model_ : SlidingDTW1NN
        The fitted 1-NN on the thinned references.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 4 * np.pi, 40)
    >>> train = {"circle": [np.c_[np.sin(t), np.cos(t)]], "line": [np.c_[t, t]]}
    >>> from handflow.plugins.segmenter.scorers import DTWScorer
    >>> DTWScorer(window=5).fit(train).scores(train["line"][0]).argmax(axis=1)[-1].item()
    1
    """

    kind = "dtw"

    def __init__(self, *, window: int = 20, thin: int = 4) -> None:
        self.window = window
        self.thin = thin

    def _fit(self, segments: dict) -> None:
        refs = {c: dtw_references(segs, int(self.thin)) for c, segs in segments.items()}
        self.model_ = SlidingDTW1NN(window=int(self.window)).fit(refs)
        return np.vstack([self.model_.scores(s) for segs in segments.values() for s in segs])

    def scores(self, X: np.ndarray) -> np.ndarray:
        X = self.check_input(X)
        return self.model_.scores(X)

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
