"""The SOM grasp manifold (docs/grasping.md; thesis 4.2.1, eq. 4.7–4.11), scikit-learn style.

A 2D lattice of ``rows × cols`` nodes with reference postures ``w_a``.  Training (eq. 4.8, 4.9)::

    Δw_a = ε(t) · exp(−‖a − a*(θ)‖² / 2σ(t)²) · (θ − w_a)

with a learning rate ``ε`` decaying ``lr[0] → lr[1]`` and a neighbourhood width ``σ`` decaying
``sigma[0] → sigma[1]`` over ``epochs`` (thesis: 0.95 → 0.05, 6 → 0.7, 300 epochs, data presented in
random order every epoch).  Documented, swappable choices:

- ``mode="online"`` (the thesis: one update per posture, vectorised over nodes) or ``"batch"``
  (one update per epoch towards the neighbourhood-weighted data means, much faster on large sets);
- ``schedule="exponential"`` (``v0 (v1/v0)^τ``, Ritter et al. 1992) or ``"linear"``, with ``τ ∈ [0, 1]``
  the fraction of updates done;
- ``init="pca"`` (nodes on the plane of the two main principal components, ±2 std — deterministic,
  topology-preserving from the start), ``"random"`` (random training postures) or an array.

Best-match search uses the PCP metric (:mod:`.pcp`), so a partially specified posture is completed
from the manifold (associative completion, eq. 4.11).  ``partial_fit`` resumes training with postures
found during use (thesis: 10 epochs, ε 0.1 → 0.05, σ 3 → 0.7).  Files: ``.npz`` of arrays + a JSON
metadata string, never pickled.
"""

from __future__ import annotations

import datetime as _dt
import json

import numba
import numpy as np
from sklearn.base import BaseEstimator
from sklearn.utils.validation import check_is_fitted

from handflow.framework.files.npz import NpzFileError, building, npz_metadata, read_npz

from .pcp import check_mask

FORMAT = "handflow.grasp_som"
FORMAT_VERSION = 1
SCHEDULES = ("exponential", "linear")
MODES = ("online", "batch")
RESUME = {"epochs": 10, "lr": (0.1, 0.05), "sigma": (3.0, 0.7)}
"""Resume-training parameters of the thesis (4.2.2) used by :meth:`SOM.partial_fit` by default."""


def decay(start: float, end: float, tau, schedule: str = "exponential"):
    """Value of a parameter decaying from ``start`` to ``end`` at progress ``tau`` ∈ [0, 1]."""
    tau = np.asarray(tau, dtype=float)
    if schedule == "exponential":
        return start * (end / start) ** tau
    if schedule == "linear":
        return start + (end - start) * tau
    raise ValueError(f"unknown schedule '{schedule}'; choose one of {', '.join(SCHEDULES)}")


def _check_postures(X, n_features: int | None = None) -> np.ndarray:
    X = np.asarray(X, dtype=float)
    if X.ndim == 1:
        X = X[None, :]
    if X.ndim != 2 or X.shape[0] == 0:
        raise ValueError(f"postures must be a non-empty (n_samples, n_joints) array, got shape {X.shape}")
    if not np.isfinite(X).all():
        raise ValueError("postures contain NaN or inf; drop or repair those rows before training")
    if n_features is not None and X.shape[1] != n_features:
        raise ValueError(f"postures have {X.shape[1]} joints but the SOM was trained on {n_features}")
    return X


class SOM(BaseEstimator):
    """Self-organising map on a 2D rectangular lattice.

    Parameters
    ----------
    rows, cols : int, default 25
        Lattice size.
    lr : (float, float), default (0.95, 0.05)
        Learning rate at the start and the end of training.
    sigma : (float, float), default (6.0, 0.7)
        Neighbourhood width (lattice units) at the start and the end of training.
    epochs : int, default 300
        Passes over the postures.
    mode : {'online', 'batch'}, default 'online'
        Update after every posture or once per epoch.
    schedule : {'exponential', 'linear'}, default 'exponential'
        How ``lr`` and ``sigma`` decay from start to end.
    init : 'pca', 'random' or array (rows, cols, d), default 'pca'
        Initial reference postures.
    random_state : int, numpy.random.Generator or None, default None
        Seed of the random init and the posture order.

    Attributes
    ----------
    nodes_ : ndarray of shape (rows, cols, d)
        Reference postures.
    grid_ : ndarray of shape (rows·cols, 2)
        Lattice coordinates (row, col) of the flat node index.
    n_features_in_ : int
        Joints per posture.
    qe_history_ : list of float
        Quantisation error after each epoch, index 0 = after init.
    n_updates_ : int
        Training rounds so far (fit + partial_fit calls).

    Examples
    --------
    >>> import numpy as np
    >>> from handflow.plugins.grasp.som import SOM
    >>> X = np.random.default_rng(0).normal(size=(30, 3))
    >>> som = SOM(rows=3, cols=4, epochs=3, init="random", random_state=0).fit(X)
    >>> som.nodes_.shape, som.transform(X).shape
    ((3, 4, 3), (30, 2))
    """

    def __init__(
        self,
        *,
        rows: int = 25,
        cols: int = 25,
        lr=(0.95, 0.05),
        sigma=(6.0, 0.7),
        epochs: int = 300,
        mode: str = "online",
        schedule: str = "exponential",
        init="pca",
        random_state=None,
    ):
        self.rows = rows
        self.cols = cols
        self.lr = lr
        self.sigma = sigma
        self.epochs = epochs
        self.mode = mode
        self.schedule = schedule
        self.init = init
        self.random_state = random_state

    # -- validation ----------------------------------------------------------------------------
    def _check_params(self) -> None:
        if int(self.rows) < 1 or int(self.cols) < 1 or int(self.rows) * int(self.cols) < 2:
            raise ValueError(f"the lattice needs at least 2 nodes, got {self.rows}×{self.cols}")
        if self.mode not in MODES:
            raise ValueError(f"unknown mode '{self.mode}'; choose one of {', '.join(MODES)}")
        if self.schedule not in SCHEDULES:
            raise ValueError(f"unknown schedule '{self.schedule}'; choose one of {', '.join(SCHEDULES)}")
        _check_pair("lr", self.lr)
        _check_pair("sigma", self.sigma)
        if int(self.epochs) < 1:
            raise ValueError(f"epochs must be ≥ 1, got {self.epochs}")

    # -- training ------------------------------------------------------------------------------
    def fit(self, X, y=None) -> SOM:
        """Initialise the lattice and train ``epochs`` epochs on postures ``X`` (n, d)."""
        self._check_params()
        X = _check_postures(X)
        rng = np.random.default_rng(self.random_state)
        r, c = int(self.rows), int(self.cols)
        self.grid_ = np.stack(np.meshgrid(np.arange(r), np.arange(c), indexing="ij"), -1).reshape(-1, 2).astype(float)
        self._lattice_d2 = None
        self.nodes_ = self._initial_nodes(X, rng).reshape(r, c, -1)
        self.n_features_in_ = X.shape[1]
        self.qe_history_ = [self.quantization_error(X)]
        self.n_updates_ = 0
        self._train(X, int(self.epochs), self.lr, self.sigma, rng)
        return self

    def partial_fit(self, X, y=None, epochs: int = RESUME["epochs"], lr=RESUME["lr"], sigma=RESUME["sigma"]) -> SOM:
        """Resume training on new postures (e.g. grasps found during use) with small parameters."""
        if not hasattr(self, "nodes_"):
            return self.fit(X)
        _check_pair("lr", lr)
        _check_pair("sigma", sigma)
        X = _check_postures(X, self.n_features_in_)
        seed = None if not isinstance(self.random_state, int) else [self.random_state, self.n_updates_]
        self._train(X, int(epochs), lr, sigma, np.random.default_rng(seed))
        return self

    def _initial_nodes(self, X: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        n = int(self.rows) * int(self.cols)
        if isinstance(self.init, str) and self.init == "random":
            return X[rng.integers(0, len(X), n)].copy()
        if isinstance(self.init, str) and self.init == "pca":
            mean = X.mean(axis=0)
            if len(X) < 2:
                return np.repeat(mean[None], n, axis=0)
            _, sv, vt = np.linalg.svd(X - mean, full_matrices=False)
            std = sv / np.sqrt(max(len(X) - 1, 1))
            axes = [std[k] * vt[k] if k < len(std) else np.zeros_like(mean) for k in (0, 1)]
            u = _span(int(self.rows))[:, None, None] * 2 * axes[0]
            v = _span(int(self.cols))[None, :, None] * 2 * axes[1]
            return (mean + u + v).reshape(n, -1)
        if isinstance(self.init, str):
            raise ValueError(f"unknown init '{self.init}'; choose pca, random or pass an array (rows·cols, d)")
        W = np.asarray(self.init, dtype=float).reshape(n, -1)
        if W.shape[1] != X.shape[1]:
            raise ValueError(f"init array has {W.shape[1]} joints, the postures {X.shape[1]}")
        return W.copy()

    def _lattice_sq(self) -> np.ndarray:
        if getattr(self, "_lattice_d2", None) is None:
            g = self.grid_
            self._lattice_d2 = ((g[:, None, :] - g[None, :, :]) ** 2).sum(-1)
        return self._lattice_d2

    def _train(self, X: np.ndarray, epochs: int, lr, sigma, rng: np.random.Generator) -> None:
        W = self.nodes_.reshape(-1, X.shape[1])
        D2 = self._lattice_sq()
        n = len(X)
        if self.mode == "online":
            total = epochs * n
            for e in range(epochs):
                order = rng.permutation(n)
                tau = (e * n + np.arange(n)) / max(total - 1, 1)
                eps = decay(lr[0], lr[1], tau, self.schedule)
                sig = decay(sigma[0], sigma[1], tau, self.schedule)
                _online_epoch(W, X, order, eps, sig, D2)
                self.qe_history_.append(self.quantization_error(X))
        else:
            for e in range(epochs):
                tau = e / max(epochs - 1, 1)
                eps = decay(lr[0], lr[1], tau, self.schedule)
                sig = decay(sigma[0], sigma[1], tau, self.schedule)
                H = np.exp(-D2[self._bmus(W, X)] / (2.0 * sig**2))  # (n, nodes)
                mass = H.sum(axis=0)
                target = (H.T @ X) / np.maximum(mass, 1e-300)[:, None]
                W += eps * (mass > 1e-12)[:, None] * (target - W)
                self.qe_history_.append(self.quantization_error(X))
        self.n_updates_ += 1

    # -- queries -------------------------------------------------------------------------------
    @property
    def postures(self) -> np.ndarray:
        """Reference postures as a flat (rows·cols, d) array (row-major node index)."""
        check_is_fitted(self, "nodes_")
        return self.nodes_.reshape(-1, self.n_features_in_)

    @staticmethod
    def _bmus(W: np.ndarray, X: np.ndarray, s: np.ndarray | None = None) -> np.ndarray:
        s = np.ones(X.shape[1]) if s is None else s
        d = ((X * X) @ s)[:, None] - 2.0 * (X * s) @ W.T + ((W * W) @ s)[None, :]  # GEMM form of Σ s (x − w)²
        return np.argmin(d, axis=1)

    def best_match(self, X, mask=None) -> np.ndarray:
        """Flat index of the best-match node of each posture under the PCP metric (eq. 4.11)."""
        X = _check_postures(X, getattr(self, "n_features_in_", None))
        return self._bmus(self.postures, X, check_mask(mask, X.shape[1]))

    def complete(self, X, mask=None) -> np.ndarray:
        """Associative completion: the best-match node postures (n, d) for (partial) postures ``X``."""
        return self.postures[self.best_match(X, mask)]

    def transform(self, X, mask=None) -> np.ndarray:
        """Lattice coordinates (row, col) of each posture's best-match node (n, 2)."""
        check_is_fitted(self, "nodes_")
        return self.grid_[self.best_match(X, mask)].copy()

    def quantization_error(self, X) -> float:
        """Mean Euclidean distance of the postures to their best-match node."""
        X = _check_postures(X, getattr(self, "n_features_in_", None))
        W = self.postures
        return float(np.mean(np.sqrt(((X - W[self._bmus(W, X)]) ** 2).sum(axis=1))))

    def topographic_error(self, X) -> float:
        """Share of postures whose best and second-best nodes are not lattice neighbours (4-neighbourhood)."""
        X = _check_postures(X, self.n_features_in_)
        W = self.postures
        d = (X * X).sum(1)[:, None] - 2.0 * X @ W.T + (W * W).sum(1)[None, :]
        two = np.argpartition(d, 1, axis=1)[:, :2]
        gap = np.abs(self.grid_[two[:, 0]] - self.grid_[two[:, 1]]).sum(axis=1)
        return float(np.mean(gap > 1.0))

    def hits(self, X) -> np.ndarray:
        """How many postures each node wins (rows, cols): the data support of a node."""
        counts = np.bincount(self.best_match(X), minlength=int(self.rows) * int(self.cols))
        return counts.reshape(int(self.rows), int(self.cols))

    def neighbour_distances(self) -> tuple[np.ndarray, np.ndarray]:
        """Euclidean distances between lattice neighbours: along rows (rows, cols−1), along columns (rows−1, cols)."""
        check_is_fitted(self, "nodes_")
        W = self.nodes_
        return (np.linalg.norm(W[:, 1:] - W[:, :-1], axis=-1), np.linalg.norm(W[1:] - W[:-1], axis=-1))

    def u_matrix(self) -> np.ndarray:
        """Mean distance of every node to its 4-neighbours (rows, cols): the inter-node distance map."""
        h, v = self.neighbour_distances()
        total = np.zeros(self.nodes_.shape[:2])
        count = np.zeros_like(total)
        total[:, :-1] += h
        total[:, 1:] += h
        total[:-1] += v
        total[1:] += v
        count[:, :-1] += 1
        count[:, 1:] += 1
        count[:-1] += 1
        count[1:] += 1
        return total / np.maximum(count, 1)


@numba.njit(cache=True)
def _online_epoch(W, X, order, eps, sig, D2):  # pragma: no cover - compiled
    """One epoch of eq. 4.8 in place: per posture the best-match node, then the Gaussian-weighted pull.

    Nodes beyond 5σ on the lattice get weights < 4e-6 and are skipped (documented cut-off).
    """
    n_nodes, d = W.shape
    for k in range(order.size):
        x = X[order[k]]
        best, best_d = 0, np.inf
        for a in range(n_nodes):
            dist = 0.0
            for j in range(d):
                diff = x[j] - W[a, j]
                dist += diff * diff
            if dist < best_d:
                best, best_d = a, dist
        inv = 1.0 / (2.0 * sig[k] * sig[k])
        reach = 25.0 * sig[k] * sig[k]
        for a in range(n_nodes):
            g = D2[best, a]
            if g <= reach:
                h = eps[k] * np.exp(-g * inv)
                for j in range(d):
                    W[a, j] += h * (x[j] - W[a, j])


def _span(n: int) -> np.ndarray:
    return np.linspace(-1.0, 1.0, n) if n > 1 else np.zeros(1)


def _check_pair(name: str, pair) -> None:
    try:
        a, b = (float(v) for v in pair)
    except (TypeError, ValueError, OverflowError):  # OverflowError: float() of a huge integer
        raise ValueError(f"{name} must be a (start, end) pair, got {pair!r}") from None
    if not (a > 0 and b > 0):
        raise ValueError(f"{name} start and end must be positive, got {pair!r}")


def save_som(som: SOM, path, metadata: dict | None = None) -> None:
    """Write a fitted SOM to ``path`` (.npz): nodes, QE history and JSON metadata (params + ``metadata``)."""
    check_is_fitted(som, "nodes_")
    params = som.get_params()
    params["lr"], params["sigma"] = list(map(float, som.lr)), list(map(float, som.sigma))
    if not isinstance(params["init"], str):
        params["init"] = "pca"
    if not isinstance(params["random_state"], (int, type(None))):
        params["random_state"] = None
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "params": params,
        "n_updates": som.n_updates_,
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        **(metadata or {}),
    }
    with open(path, "wb") as fh:
        np.savez(
            fh,
            nodes=som.nodes_,
            qe_history=np.asarray(som.qe_history_, dtype=float),
            metadata=np.array(json.dumps(meta)),
        )


def load_som(path) -> tuple[SOM, dict]:
    """Read a SOM file written by :func:`save_som` → (fitted SOM, metadata dict); a bad file raises
    :class:`~handflow.framework.files.npz.NpzFileError` (a ``ValueError``) naming it."""
    what, hint = "grasp SOM", "train it again with `handflow grasp-som` (docs/grasping.md)"
    arrays = read_npz(path, what, hint)
    meta = npz_metadata(arrays, path, what, hint, fmt=(FORMAT, FORMAT_VERSION, "format_version"))
    if "nodes" not in arrays or "qe_history" not in arrays:
        raise NpzFileError(f"{path}: not a handflow grasp SOM file (needs 'nodes' and 'qe_history'); {hint}")
    nodes, qe = arrays["nodes"], arrays["qe_history"]
    with building(path, what, hint):
        params = dict(meta["params"])
        params["lr"], params["sigma"] = tuple(params["lr"]), tuple(params["sigma"])
        som = SOM(**params)
        if nodes.ndim != 3 or nodes.dtype.kind != "f" or not np.isfinite(nodes).all():
            raise ValueError(f"nodes must be a finite (rows, cols, d) array, got shape {nodes.shape}")
        r, c, d = nodes.shape
        som.nodes_ = nodes.astype(float)
        som.grid_ = np.stack(np.meshgrid(np.arange(r), np.arange(c), indexing="ij"), -1).reshape(-1, 2).astype(float)
        som.n_features_in_ = d
        som.qe_history_ = list(map(float, qe))
        som.n_updates_ = int(meta.get("n_updates", 1))
    return som, meta
