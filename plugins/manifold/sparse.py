"""UKR on neighbour lists: cost and memory linear in the number of points (docs/training.md).

With compact kernels (:data:`~handflow.plugins.manifold.kernels.COMPACT_KERNELS`) ``K_ij`` is
zero unless every latent coordinate of ``x_i − x_j`` lies inside its kernel's support.  In
coordinates scaled by ``1/support`` that support is the unit ball of the maximum norm
(periodic dimensions on a torus of circumference ``π/support``), so a ``cKDTree`` finds all
non-zero pairs.  The objective and gradient of ``objective.py`` are then sums over those
pairs only: O(N·k·d) time and O(N·k) memory for k neighbours per point.

Rebuild schedule (Verlet list, documented choice): pairs are searched up to radius
``1 + skin`` (``skin`` = 0.1 supports: fastest of 0.1–0.5 at N = 20 000, q = 2) and the list is rebuilt only once some point has
moved more than ``skin/2`` supports in some coordinate since the last build, so no pair
inside the support is ever missed and the result equals the dense one up to rounding.
Latents packed so densely that a point has more than ``MAX_MEAN_NEIGHBOURS`` neighbours are
refused (value ``inf`` without gradient, so the initial scale search skips such scales).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix
from scipy.spatial import cKDTree

from .kernels import COMPACT_KERNELS, ProductKernel
from .objective import Objective
from .projection import Manifold
from .validation import InvalidInputError, parse_latent

# Documented choice: above this many points ``sparse="auto"`` takes the neighbour-list path
# (measured crossover well below it, docs/benchmarks.md "UKR at scale").
SPARSE_MIN_N = 2000
SKIN = 0.1
# Documented choice: more neighbours per point than this (estimated on 256 probes before each
# rebuild) means the kernels are too wide to be sparse; memory would approach the dense N².
MAX_MEAN_NEIGHBOURS = 256
SPARSE_MODES = ("auto", True, False, "float32")
_TINY = 1e-300


class TooManyNeighbours(InvalidInputError):
    """The latents are so concentrated that the neighbour lists would not be sparse."""


def compact_advice(kernel: ProductKernel) -> str:
    """Which compact kernel to configure instead of each non-compact one."""
    subs = []
    for l, k in enumerate(kernel.kernels):
        if not k.compact:
            if k.periodic:
                subs.append(f"latent[{l}]: {k.name} (beta {k.beta:g}) -> periodic_quartic with beta > 1")
            else:
                subs.append(f"latent[{l}]: {k.name} -> quartic or epanechnikov")
    return "; ".join(subs)


def use_sparse(mode, kernel: ProductKernel, n_points: int) -> bool:
    """Resolve the ``sparse`` hyper-parameter (``auto``: compact kernels and N ≥ SPARSE_MIN_N)."""
    if mode not in SPARSE_MODES or isinstance(mode, (int, float)) and not isinstance(mode, bool):
        raise InvalidInputError(f"sparse must be one of 'auto', true, false, 'float32'; got {mode!r}")
    compact = all(k.compact for k in kernel.kernels)
    if mode == "auto":
        return compact and n_points >= SPARSE_MIN_N
    if mode and not compact:
        raise InvalidInputError(
            f"sparse training needs compact kernels ({', '.join(COMPACT_KERNELS)}); change {compact_advice(kernel)}"
        )
    return bool(mode)


def dense_advice(model, n_points: int):
    """Message for ``handflow train`` when a large set would take the quadratic dense path."""
    kernel, _ = parse_latent(model.latent)
    if n_points < SPARSE_MIN_N or model.sparse is False or all(k.compact for k in kernel.kernels):
        return None
    gb = 8 * n_points**2 / 1e9
    return (
        f"{n_points} points with non-compact kernels train on the dense path: time and memory grow "
        f"with N² (one {n_points}×{n_points} kernel matrix is {gb:.1f} GB). For cost linear in N "
        f"choose compact kernels: {compact_advice(kernel)} (docs/training.md, 'Training at scale')"
    )


def pair_kernel(kernel: ProductKernel, deltas, with_du=False):
    """``K`` on per-dimension lists of latent differences and, optionally, ``∂K/∂δ_l``.

    Periodic kernels depend on δ only through ``sin δ`` and ``sin 2δ``, so differences need
    no wrapping."""
    phis, dks = [], []
    for k, delta in zip(kernel.kernels, deltas):
        s = np.sin(delta) if k.periodic else delta
        u = (k.beta**2) * s * s
        phis.append(k.phi(u))
        if with_du:
            du = (k.beta**2) * (np.sin(2 * delta) if k.periodic else 2 * delta)
            dks.append(k.dphi(u) * du)
    K = np.prod(phis, axis=0) if len(phis) > 1 else phis[0]
    if not with_du:
        return K, None
    D = []
    for l in range(kernel.q):
        d = dks[l]
        for m in range(kernel.q):
            if m != l:
                d = d * phis[m]
        D.append(d)
    return K, D


class NeighbourIndex:
    """Scaled latent coordinates and their ``cKDTree`` (support = unit max-norm ball)."""

    def __init__(self, kernel: ProductKernel):
        if not all(k.compact for k in kernel.kernels):
            raise InvalidInputError(
                f"the neighbour-list path needs compact kernels ({', '.join(COMPACT_KERNELS)}); "
                f"change {compact_advice(kernel)}"
            )
        self.kernel = kernel
        self.scale = np.array([1.0 / k.support for k in kernel.kernels])
        self.box = np.where(kernel.periodic, np.pi * self.scale, 0.0)

    def scaled(self, X):
        Z = np.asarray(X, dtype=float) * self.scale
        p = self.kernel.periodic
        Z[:, p] = np.mod(Z[:, p], self.box[p])
        return Z

    def tree(self, X):
        return cKDTree(self.scaled(X), boxsize=self.box if self.kernel.periodic.any() else None)

    def displacement(self, X, X_ref):
        """Largest coordinate move in supports (periodic moves taken modulo π)."""
        delta = X - X_ref
        p = self.kernel.periodic
        delta[:, p] = np.mod(delta[:, p] + np.pi / 2, np.pi) - np.pi / 2
        return float(np.max(np.abs(delta * self.scale), initial=0.0))

    @staticmethod
    def deltas(A, B, rows, cols, dtype=np.float64):
        """Per latent dimension the differences ``a_rows − b_cols``."""
        return [(A[:, l][rows] - B[:, l][cols]).astype(dtype, copy=False) for l in range(A.shape[1])]


class VerletPairs:
    """Unordered pairs ``i < j`` within ``1 + skin`` supports and the symmetric CSR pattern
    they fill, kept up to date as the latents move (rebuilt once a point has moved more than
    ``skin/2`` supports).  Pair values are computed once per unordered pair."""

    def __init__(self, index: NeighbourIndex, skin=SKIN):
        self.index, self.skin = index, float(skin)
        self.X_ref, self.n_builds = None, 0

    def update(self, X):
        if self.X_ref is not None and self.index.displacement(X, self.X_ref) <= self.skin / 2:
            return
        N = len(X)
        tree = self.index.tree(X)
        probe = tree.data[np.linspace(0, N - 1, min(N, 256)).astype(int)]
        mean_k = float(np.mean(tree.query_ball_point(probe, 1.0 + self.skin, p=np.inf, return_length=True)))
        if mean_k > MAX_MEAN_NEIGHBOURS:
            raise TooManyNeighbours(
                f"about {mean_k:.0f} latent neighbours per point inside the kernel support (limit "
                f"{MAX_MEAN_NEIGHBOURS}): the kernels are too wide for these latents; raise beta"
            )
        pairs = tree.query_pairs(1.0 + self.skin, p=np.inf, output_type="ndarray")
        self.i, self.j = pairs[:, 0], pairs[:, 1]
        # CSR of both directions; its data holds ±(pair number + 1): the gather map and sign
        tag = np.arange(1, len(pairs) + 1, dtype=float)
        full = coo_matrix((np.r_[tag, -tag], (np.r_[self.i, self.j], np.r_[self.j, self.i])), shape=(N, N)).tocsr()
        self.indices, self.indptr = full.indices, full.indptr
        self.perm = np.abs(full.data).astype(np.intp) - 1
        self.sign = np.sign(full.data)
        self.X_ref, self.n_builds = X.copy(), self.n_builds + 1

    def matrix(self, values, antisymmetric=False):
        """Symmetric (or antisymmetric) CSR matrix from one value per unordered pair."""
        data = values[self.perm]
        if antisymmetric:
            data *= self.sign.astype(data.dtype, copy=False)
        n = len(self.indptr) - 1
        return csr_matrix((data, self.indices, self.indptr), shape=(n, n))

    @property
    def mean_neighbours(self) -> float:
        return 2 * len(self.i) / max(len(self.indptr) - 1, 1)


class SparseObjective(Objective):
    """:class:`~handflow.plugins.manifold.objective.Objective` evaluated on neighbour pairs.

    Same terms, same gradient (``∂R/∂x_al = Σ_j G_aj D_aj,l − Σ_i G_ia D_ia,l``), with the
    sums over j and i running over the sparse pattern: with ``D_l`` antisymmetric,
    ``Σ_j G_aj D_aj = −(2/N)(y_a·(D_l E/s)_a − (D_l c/s)_a)`` and
    ``Σ_i G_ia D_ia = (2/N)(E_a·(D_l Y)_a − c_a (D_l 1)_a)/s_a`` — one sparse product per
    latent dimension.  ``dtype=np.float32`` evaluates the pair terms and products in single
    precision (docs/benchmarks.md measures the error); value and gradient return as float64.
    """

    def __init__(self, Y, kernel, layout, *, skin=SKIN, dtype=np.float64, **kwargs):
        super().__init__(Y, kernel, layout, **kwargs)
        self.dtype = np.dtype(dtype)
        self.pairs = VerletPairs(NeighbourIndex(kernel), skin)
        self._Yc = self.Y.astype(self.dtype)

    def reconstruction(self, X, gradient=True):
        N, Y, pairs = self.N, self.Y, self.pairs
        d = Y.shape[1]
        try:
            pairs.update(X)
        except TooManyNeighbours:
            if gradient:
                raise
            return np.inf, None  # e.g. a too small trial scale in init.scale_search
        K, D = pair_kernel(self.kernel, pairs.index.deltas(X, X, pairs.i, pairs.j, self.dtype), gradient)
        T = pairs.matrix(K) @ np.hstack([self._Yc, np.ones((N, 1), self.dtype)])
        T = T.astype(float)
        if not self.loo_cv:  # K(0) = 1 on the diagonal
            T += np.hstack([Y, np.ones((N, 1))])
        s = np.maximum(T[:, -1], _TINY)
        F = T[:, :d] / s[:, None]
        E = Y - F
        R = float(np.einsum("ij,ij->", E, E)) / N
        if not gradient:
            return R, None
        c = np.einsum("ij,ij->i", E, F)
        rhs = np.hstack([E / s[:, None], (c / s)[:, None], Y, np.ones((N, 1))]).astype(self.dtype)
        grad = np.empty_like(X)
        for l in range(self.kernel.q):
            V = (pairs.matrix(D[l], antisymmetric=True) @ rhs).astype(float)
            toward = np.einsum("nd,nd->n", Y, V[:, :d]) - V[:, d]
            back = (np.einsum("nd,nd->n", E, V[:, d + 1 : 2 * d + 1]) - c * V[:, -1]) / s
            grad[:, l] = (-2.0 / N) * (toward + back)
        return R, grad


class SparseManifold(Manifold):
    """f and its Jacobian summed over the training points inside each query's kernel support
    (same neighbour index as training); the projection g is inherited unchanged."""

    def __init__(self, kernel: ProductKernel, X, Y):
        self.index = NeighbourIndex(kernel)
        self._tree = self.index.tree(X)
        super().__init__(kernel, X, Y)

    def _pairs(self, Xq):
        hits = self._tree.query_ball_point(self.index.scaled(Xq), 1.0, p=np.inf)
        counts = np.fromiter((len(h) for h in hits), dtype=np.int64, count=len(hits))
        cols = np.concatenate([np.asarray(h, dtype=np.int64) for h in hits]) if counts.sum() else np.zeros(0, int)
        rows = np.repeat(np.arange(len(Xq)), counts)
        return rows, cols, np.r_[0, np.cumsum(counts)]

    def _weights(self, Xq, with_du):
        rows, cols, indptr = self._pairs(Xq)
        K, D = pair_kernel(self.kernel, self.index.deltas(np.asarray(Xq, dtype=float), self.X, rows, cols), with_du)
        shape = (len(Xq), len(self.X))

        def mat(data):
            return csr_matrix((data, cols, indptr), shape=shape)

        return mat(K), [mat(x) for x in D] if with_du else None

    def f(self, Xq):
        K, _ = self._weights(Xq, False)
        T = K @ np.hstack([self.Y, np.ones((len(self.Y), 1))])
        return T[:, :-1] / np.maximum(T[:, -1], _TINY)[:, None]

    def f_and_jacobian(self, Xq):
        K, D = self._weights(Xq, True)
        Y1 = np.hstack([self.Y, np.ones((len(self.Y), 1))])
        T = K @ Y1
        S = np.maximum(T[:, -1], _TINY)[:, None]
        F = T[:, :-1] / S
        dT = [Dl @ Y1 for Dl in D]
        J = np.stack([(t[:, :-1] - F * t[:, -1:]) / S for t in dT], axis=2)
        return F, J
