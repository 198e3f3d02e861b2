"""The mapping f and the (masked) orthogonal projection g (docs/training.md).

``g_s(y) = argmin_x Σ_k s_k (y_k − f_k(x))²``, batch-vectorised:

1. coarse search: the best of the candidate latents (the training latents, whose images
   ``f(x_i)`` are cached) under the masked distance, one GEMM for the whole batch;
2. refinement: a few Levenberg–Marquardt (damped Gauss–Newton) steps per point, all points
   at once; periodic coordinates wrap modulo π.

Documented choice: non-periodic coordinates are clamped to the box spanned by the training
latents (f is a convex combination of the y_i and only extrapolates by flattening).
"""

from __future__ import annotations

import numpy as np

from .kernels import ProductKernel

_TINY = 1e-300
_BLOCK = 1 << 22  # coarse-search distances held at once (32 MB): memory stays O(N) per batch


class Manifold:
    """f and g for fixed training data ``Y`` (N×d) and latents ``X`` (N×q)."""

    def __init__(self, kernel: ProductKernel, X, Y):
        self.kernel = kernel
        self.X = np.ascontiguousarray(X, dtype=float)
        self.Y = np.ascontiguousarray(Y, dtype=float)
        free = ~kernel.periodic
        self.lower = np.where(free, self.X.min(axis=0), -np.inf)
        self.upper = np.where(free, self.X.max(axis=0), np.inf)
        self.candidates = self.f(self.X)

    def f(self, Xq):
        """``f(x) = Σ_i y_i K(x − x_i) / Σ_j K(x − x_j)`` for every row of Xq (M×q)."""
        K = self.kernel.matrix(Xq, self.X, stabilise=True)
        return (K @ self.Y) / np.maximum(K.sum(axis=1), _TINY)[:, None]

    def f_and_jacobian(self, Xq):
        """f (M×d) and ``J = ∂f/∂x`` (M×d×q)."""
        K, C = self.kernel.matrix(Xq, self.X, with_du=True, stabilise=True)
        S = np.maximum(K.sum(axis=1), _TINY)[:, None]
        F = (K @ self.Y) / S
        dK = self.kernel.derivatives(K, C, Xq, self.X)
        J = np.stack([(D @ self.Y - F * D.sum(axis=1)[:, None]) / S for D in dK], axis=2)
        return F, J

    def _clamp_wrap(self, X):
        return self.kernel.wrap(np.clip(X, self.lower, self.upper))

    def _nearest_candidates(self, Yq, w, w2):
        """Index of the best candidate per row, in row blocks of at most ``_BLOCK`` distances."""
        Fc = self.candidates
        best = np.empty(len(Yq), dtype=np.int64)
        step = max(1, _BLOCK // max(len(Fc), 1))
        for a in range(0, len(Yq), step):
            Yw, wb = Yq[a : a + step] * w2[a : a + step], w2[a : a + step]
            dist = Yw @ (-2.0 * Fc.T) + (wb @ (Fc * Fc).T if w.ndim == 2 else (Fc * Fc) @ w)
            best[a : a + step] = np.argmin(dist, axis=1)
        return best

    def project(self, Yq, weights=None, n_iter=10, tol=1e-7):
        """Masked orthogonal projection of every row of Yq (M×d); ``weights`` (d,) or (M×d)."""
        Yq = np.asarray(Yq, dtype=float)
        w = np.ones(Yq.shape[1]) if weights is None else np.asarray(weights, dtype=float)
        w2 = np.broadcast_to(w, Yq.shape)
        x = self.X[self._nearest_candidates(Yq, w, w2)].copy()
        F, J = self.f_and_jacobian(x)
        r = Yq - F
        err = np.einsum("md,md->m", w2 * r, r)
        mu = np.full(len(x), 1e-3)
        eye = np.eye(self.kernel.q)
        for _ in range(n_iter):
            Jw = J * w2[:, :, None]
            A = np.einsum("mdq,mdp->mqp", Jw, J)
            g = np.einsum("mdq,md->mq", Jw, r)
            diag = np.einsum("mqq->mq", A)
            A_damped = A + (mu[:, None] * (diag + 1e-12))[:, :, None] * eye
            step = np.linalg.solve(A_damped, g[:, :, None])[:, :, 0]
            x_new = self._clamp_wrap(x + step)
            F_new, J_new = self.f_and_jacobian(x_new)
            r_new = Yq - F_new
            err_new = np.einsum("md,md->m", w2 * r_new, r_new)
            ok = err_new <= err
            x[ok], F[ok], J[ok], r[ok], err[ok] = x_new[ok], F_new[ok], J_new[ok], r_new[ok], err_new[ok]
            mu = np.where(ok, mu / 3.0, mu * 4.0)
            if np.max(np.abs(step)) < tol:
                break
        return x
