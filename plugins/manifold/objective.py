"""Structured UKR objective and its analytic gradient (docs/training.md).

``E(X) = R_cv(X) + λ_cseq E_cseq(X) + λ_pvar E_pvar(X)`` with

* ``R_cv = (1/N) ||Y − Y B_cv(X)||_F²``; ``B_cv`` = kernel matrix with zeroed diagonal, columns
  normalised to sum 1 (leave-one-out, §4).  ``loo_cv=False`` gives the plain ``R``.
* ``E_cseq = Σ_σ Σ_i sin²(x_i,t − x_i−1,t)`` cyclic (periodic time dimension, the first point
  follows the last) or ``Σ (x_i,t − x_i−1,t)²`` without wrap-around (non-periodic time
  dimension) — documented choice: cyclicity follows the periodicity of the time kernel.
* ``E_pvar = Σ_σ Σ_{k≠t} (1/N_σ) Σ_i (x_ik − ⟨x_k⟩_σ)²``.

Gradient of R (hand-derived, row convention: Y is N×d, point j is reconstructed by column j):
with ``s_j = Σ_i K_ij``, ``F_j = Σ_i K_ij y_i / s_j``, ``E_j = y_j − F_j``, ``c_j = E_j·F_j``::

    ∂R/∂K_ij = G_ij = −(2/N) (y_i·E_j − c_j) / s_j      (chain rule through the normalisation)

and ``K_ij = K(x_i − x_j)``, so ``∂R/∂x_al = Σ_j G_aj ∂K_aj/∂δ_l − Σ_i G_ia ∂K_ia/∂δ_l``.
``∂K/∂δ_l = C_l ∘ (P_l Q_lᵀ)`` is low rank in the pair (kernels.py), so both sums reduce to two
GEMMs of the N×N matrix with thin (N × d·rank) blocks — no N×N temporaries besides K.
"""

from __future__ import annotations

import numpy as np

from .kernels import ProductKernel

_TINY = 1e-300


class SequenceLayout:
    """Sequence membership of the N points, in chronological order within each sequence."""

    def __init__(self, sequence_ids: np.ndarray):
        ids = np.asarray(sequence_ids)
        self.labels, self.index = np.unique(ids, return_inverse=True)
        self.n_sequences = len(self.labels)
        self.counts = np.bincount(self.index, minlength=self.n_sequences)
        order = np.argsort(self.index, kind="stable")
        same = self.index[order[1:]] == self.index[order[:-1]]
        self.pairs = np.stack([order[:-1][same], order[1:][same]])  # (prev, next)
        starts = np.r_[0, np.cumsum(self.counts)[:-1]]
        last = order[starts + self.counts - 1]
        self.closing = np.stack([last, order[starts]])  # last -> first

    def transitions(self, cyclic: bool) -> np.ndarray:
        return np.hstack([self.pairs, self.closing]) if cyclic else self.pairs

    def positions(self) -> np.ndarray:
        """Index of every point inside its sequence (0 … N_σ−1)."""
        order = np.argsort(self.index, kind="stable")
        starts = np.r_[0, np.cumsum(self.counts)[:-1]]
        pos = np.empty(len(self.index), dtype=int)
        pos[order] = np.arange(len(order)) - np.repeat(starts, self.counts)
        return pos


class Objective:
    """Callable ``X (N×q) -> (E, ∂E/∂X)``; components are exposed for tests and plots."""

    def __init__(
        self,
        Y,
        kernel: ProductKernel,
        layout: SequenceLayout,
        *,
        time_dim=None,
        lambda_cseq=0.0,
        lambda_pvar=0.0,
        loo_cv=True,
    ):
        self.Y = np.ascontiguousarray(Y, dtype=float)
        self.N = self.Y.shape[0]
        self.kernel = kernel
        self.layout = layout
        self.time_dim = time_dim
        self.lambda_cseq = float(lambda_cseq)
        self.lambda_pvar = float(lambda_pvar)
        self.loo_cv = bool(loo_cv)
        self.n_evaluations = 0
        if time_dim is not None:
            self._cyclic = bool(kernel.periodic[time_dim])
            self._trans = layout.transitions(self._cyclic)
            self._param_dims = [l for l in range(kernel.q) if l != time_dim]

    # -- reconstruction error -----------------------------------------------------------------
    def reconstruction(self, X, gradient=True):
        """``R_cv`` (or ``R`` without LOO) and its gradient.

        ``G`` is never formed.  With ``W_g = (YEᵀ − 1cᵀ) ∘ M_g diag(1/s)`` (``M = −K/2`` for the
        fused exponential dimensions, ``C_l`` for a finite-support one; both symmetric):
        ``W Q = rowdot(Y, M (E∘Q/s)) − M (c∘Q/s)`` and
        ``Wᵀ P = (rowdot(E, M (Y∘P)) − c ∘ M P) / s``.  The ``M(Y∘P), M P`` products of the
        exponential group and the column sums s share one GEMM with ``K Y``.
        """
        N, Y, kern = self.N, self.Y, self.kernel
        d = Y.shape[1]
        out = kern.matrix(X, X, with_du=gradient)
        K, C = out if gradient else (out, None)
        if self.loo_cv:
            np.fill_diagonal(K, 0.0)
        groups = []
        if gradient:
            if kern.exp_dims:
                groups.append((kern.exp_dims, K, -0.5))
            groups += [([l], C[l], 1.0) for l in kern.fin_dims]
        factors = [kern.du_factors(dims, X, X) for dims, _, _ in groups]

        def yp_block(P):
            return [(Y[:, None, :] * P[:, :, None]).reshape(N, -1), P]

        fused = bool(groups) and groups[0][1] is K
        T = K @ np.hstack([Y] + (yp_block(factors[0][0]) if fused else []) + [np.ones((N, 1))])
        s = np.maximum(T[:, -1], _TINY)  # column sums of K (K is symmetric)
        T = T[:, :-1] / s[:, None]
        F = T[:, :d]
        E = Y - F
        R = float(np.einsum("ij,ij->", E, E)) / N
        if not gradient:
            return R, None
        c = np.einsum("ij,ij->i", E, F)
        grad = np.zeros_like(X)
        for n, ((dims, M, scale), (P, Q, bounds)) in enumerate(zip(groups, factors)):
            r = P.shape[1]
            U = T[:, d:] if (n == 0 and fused) else (M @ np.hstack(yp_block(P))) / s[:, None]
            V = M @ (np.hstack([(E[:, None, :] * Q[:, :, None]).reshape(N, -1), c[:, None] * Q]) / s[:, None])
            WQ = np.einsum("nd,nrd->nr", Y, V[:, : r * d].reshape(N, r, d)) - V[:, r * d :]
            WtP = np.einsum("nd,nrd->nr", E, U[:, : r * d].reshape(N, r, d)) - c[:, None] * U[:, r * d :]
            prod = (-2.0 * scale / N) * (P * WQ - Q * WtP)
            for l, lo, hi in zip(dims, bounds[:-1], bounds[1:]):
                grad[:, l] = prod[:, lo:hi].sum(axis=1)
        return R, grad

    # -- structure penalties ------------------------------------------------------------------
    def cseq(self, X):
        """``E_cseq`` and its gradient (zero without a time dimension)."""
        grad = np.zeros_like(X)
        if self.time_dim is None:
            return 0.0, grad
        a, b = self._trans
        delta = X[b, self.time_dim] - X[a, self.time_dim]
        if self._cyclic:
            value, d = np.sum(np.sin(delta) ** 2), np.sin(2 * delta)
        else:
            value, d = np.sum(delta**2), 2 * delta
        grad[:, self.time_dim] = np.bincount(b, d, minlength=self.N) - np.bincount(a, d, minlength=self.N)
        return float(value), grad

    def pvar(self, X):
        """``E_pvar`` and its gradient (zero without a time dimension)."""
        grad = np.zeros_like(X)
        if self.time_dim is None or not self._param_dims:
            return 0.0, grad
        lay, dims = self.layout, self._param_dims
        idx, n = lay.index, lay.counts
        Xp = X[:, dims]
        means = (
            np.stack([np.bincount(idx, Xp[:, k], minlength=lay.n_sequences) for k in range(len(dims))], 1) / n[:, None]
        )
        dev = Xp - means[idx]
        w = 1.0 / n[idx]
        grad[:, dims] = 2.0 * dev * w[:, None]
        return float(np.sum(dev**2 * w[:, None])), grad

    # -- total ---------------------------------------------------------------------------------
    def __call__(self, X, gradient=True):
        """Total objective ``E(X)`` and (optionally) its gradient."""
        self.n_evaluations += 1
        value, grad = self.reconstruction(X, gradient)
        for lam, term in ((self.lambda_cseq, self.cseq), (self.lambda_pvar, self.pvar)):
            if lam:
                v, g = term(X)
                value += lam * v
                if gradient:
                    grad += lam * g
        return value, grad

    def components(self, X) -> dict:
        """Unweighted terms at X (for logs and plots)."""
        return {
            "R_cv" if self.loo_cv else "R": self.reconstruction(X, False)[0],
            "E_cseq": self.cseq(X)[0],
            "E_pvar": self.pvar(X)[0],
        }
