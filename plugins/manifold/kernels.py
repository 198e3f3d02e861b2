"""Univariate UKR kernels and their product (docs/training.md).

Every kernel is written as a *profile* ``phi`` of a squared distance ``u``:

* gaussian      ``u = β² δ²``       ``k = exp(-u/2)``
* periodic      ``u = β² sin²(δ)``  ``k = exp(-u/2)``   (period π, lives on [0, π))
* epanechnikov  ``u = β² δ²``       ``k = [1 - u]_+``
* quartic       ``u = β² δ²``       ``k = [1 - u]_+²``
* periodic_quartic ``u = β² sin²(δ)`` ``k = [1 - u]_+²`` (period π, compact for β > 1:
  support ``|sin δ| < 1/β``)

The finite-support ones (:data:`COMPACT_KERNELS`) allow the neighbour-list objective of
``sparse.py`` whose cost grows linearly with the number of points.

Prefactors are never computed: they cancel in the Nadaraya–Watson ratio (§2).

Both ``u(a_i - b_j)`` and ``du/dδ (a_i - b_j)`` are *low-rank* in the pair (i, j):
``u_ij = Σ_r L_ir R_jr``.  This is the hot-path trick of this package: the N×N squared
distances come out of one small matrix product instead of N² trigonometric calls, and gradient
sums over (i, j) reduce to products of an N×N weight matrix with a few columns.  Differences
are centred first (translation invariance) to limit cancellation in ``a² - 2ab + b²``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

KernelName = Literal["gaussian", "periodic", "quartic", "epanechnikov", "periodic_quartic"]
KERNEL_NAMES: tuple[str, ...] = get_args(KernelName)
COMPACT_KERNELS = ("quartic", "epanechnikov", "periodic_quartic")


@dataclass(frozen=True)
class Kernel:
    """One univariate kernel: ``name`` in :data:`KERNEL_NAMES`, inverse bandwidth ``beta``."""

    name: str
    beta: float

    def __post_init__(self):
        if self.name not in KERNEL_NAMES:
            raise ValueError(f"unknown kernel {self.name!r}; choose one of {', '.join(KERNEL_NAMES)}")
        if not (np.isfinite(self.beta) and self.beta > 0):
            raise ValueError(f"kernel beta must be a positive finite number, got {self.beta!r}")

    @property
    def periodic(self) -> bool:
        return self.name in ("periodic", "periodic_quartic")

    @property
    def compact(self) -> bool:
        """True when ``k(δ) = 0`` outside a finite support (``periodic_quartic`` needs β > 1)."""
        return self.name in COMPACT_KERNELS and (self.name != "periodic_quartic" or self.beta > 1)

    @property
    def support(self) -> float:
        """Half-width of the support in latent units (``inf`` for non-compact kernels)."""
        if not self.compact:
            return np.inf
        return float(np.arcsin(1.0 / self.beta)) if self.periodic else 1.0 / self.beta

    @property
    def exp_profile(self) -> bool:
        """True when ``k = exp(-u/2)``: such factors multiply by adding their ``u``."""
        return self.name in ("gaussian", "periodic")

    # -- low-rank factors -------------------------------------------------------------------
    def u_factors(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(L, R) with ``L @ R.T == u(a_i - b_j)`` for coordinate vectors a (M,), b (N,)."""
        b2 = self.beta**2
        if self.periodic:
            ca, sa, cb, sb = np.cos(2 * a), np.sin(2 * a), np.cos(2 * b), np.sin(2 * b)
            one_a, one_b = np.ones_like(a), np.ones_like(b)
            return (0.5 * b2 * np.stack([one_a, ca, sa], 1), np.stack([one_b, -cb, -sb], 1))
        c = b.mean() if b.size else 0.0
        a, b = a - c, b - c
        return (b2 * np.stack([a * a, a, np.ones_like(a)], 1), np.stack([np.ones_like(b), -2 * b, b * b], 1))

    def du_factors(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(P, Q) with ``P @ Q.T == du/dδ`` at ``δ = a_i - b_j``."""
        b2 = self.beta**2
        if self.periodic:  # d/dδ β² sin²δ = β² sin 2δ = β² (sin2a cos2b − cos2a sin2b)
            return (b2 * np.stack([np.sin(2 * a), np.cos(2 * a)], 1), np.stack([np.cos(2 * b), -np.sin(2 * b)], 1))
        return (2 * b2 * np.stack([a, np.ones_like(a)], 1), np.stack([np.ones_like(b), -b], 1))

    # -- profile ----------------------------------------------------------------------------
    def phi(self, u: np.ndarray) -> np.ndarray:
        if self.exp_profile:
            return np.exp(-0.5 * u)
        p = np.clip(1.0 - u, 0.0, None)
        return p if self.name == "epanechnikov" else p * p

    def dphi(self, u: np.ndarray) -> np.ndarray:
        """d phi / d u (the Epanechnikov kink at u = 1 takes the inside value)."""
        if self.exp_profile:
            return -0.5 * np.exp(-0.5 * u)
        inside = u < 1.0
        if self.name == "epanechnikov":
            return -inside.astype(float)
        return -2.0 * np.clip(1.0 - u, 0.0, None)

    # -- plain elementwise versions (tests, plotting) ----------------------------------------
    def __call__(self, delta: np.ndarray) -> np.ndarray:
        """k(δ) evaluated elementwise on differences (reference implementation)."""
        s = np.sin(delta) if self.periodic else delta
        return self.phi(self.beta**2 * s * s)

    def derivative(self, delta: np.ndarray) -> np.ndarray:
        """dk/dδ elementwise (reference implementation)."""
        s = np.sin(delta) if self.periodic else delta
        du = self.beta**2 * (np.sin(2 * delta) if self.periodic else 2 * delta)
        return self.dphi(self.beta**2 * s * s) * du


def as_kernel(spec) -> Kernel:
    """Accept a :class:`Kernel`, a ``(name, beta)`` pair or a dict with ``kernel``/``beta``."""
    if isinstance(spec, Kernel):
        return spec
    if isinstance(spec, dict):
        return Kernel(str(spec["kernel"]), float(spec["beta"]))
    name, beta = spec
    return Kernel(str(name), float(beta))


class ProductKernel:
    """Multivariate kernel ``K(x - x') = Π_l k_l(x_l - x'_l; β_l)`` (§2).

    All exponential-profile dimensions are fused into a single ``exp`` of their summed
    low-rank exponent.  ``stabilise=True`` shifts that exponent row-wise so its maximum is 0:
    harmless wherever rows are normalised (f, projection) and it keeps far-away queries from
    underflowing to 0/0.
    """

    def __init__(self, kernels):
        self.kernels = tuple(as_kernel(k) for k in kernels)
        if not self.kernels:
            raise ValueError("the latent layout needs at least one dimension")
        self.q = len(self.kernels)
        self.periodic = np.array([k.periodic for k in self.kernels])
        self.exp_dims = [l for l, k in enumerate(self.kernels) if k.exp_profile]
        self.fin_dims = [l for l, k in enumerate(self.kernels) if not k.exp_profile]

    def du_factors(self, dims, A, B):
        """Stacked (P, Q) of ``du_l/dδ`` for ``dims``; column bounds of each dimension."""
        P, Q = zip(*(self.kernels[l].du_factors(A[:, l], B[:, l]) for l in dims))
        return np.hstack(P), np.hstack(Q), np.cumsum([0] + [p.shape[1] for p in P])

    def matrix(self, A, B, *, with_du=False, stabilise=False):
        """K(A_i - B_j) (M×N).

        With ``with_du`` also returns ``C``: per latent dimension the matrix ``∂K/∂u_l``
        (``None`` for exponential-profile dimensions, whose ``∂K/∂u_l`` is ``-K/2``), so that
        ``∂K/∂δ_l = C_l ∘ (P_l Q_lᵀ)`` with the low-rank ``du_factors``.
        """
        if self.exp_dims:
            Ls, Rs = zip(*(self.kernels[l].u_factors(A[:, l], B[:, l]) for l in self.exp_dims))
            expo = (-0.5 * np.hstack(Ls)) @ np.hstack(Rs).T  # -u/2, summed over dims
            if stabilise:
                expo -= expo.max(axis=1, keepdims=True)
            K = np.exp(expo, out=expo)
        else:
            K = np.ones((A.shape[0], B.shape[0]))
        fin_u = []
        for l in self.fin_dims:
            L, R = self.kernels[l].u_factors(A[:, l], B[:, l])
            fin_u.append(L @ R.T)
        fin_k = [self.kernels[l].phi(u) for l, u in zip(self.fin_dims, fin_u)]
        K_exp = K.copy() if (with_du and fin_k) else None
        for k in fin_k:
            K *= k
        if not with_du:
            return K
        C = [None] * self.q
        for n, l in enumerate(self.fin_dims):
            c = self.kernels[l].dphi(fin_u[n]) * K_exp
            for m, k in enumerate(fin_k):
                if m != n:
                    c *= k
            C[l] = c
        return K, C

    def derivatives(self, K, C, A, B):
        """Explicit ``∂K/∂δ_l`` (list over l) for small M×N blocks (projection)."""
        out = []
        for l in range(self.q):
            P, Q = self.kernels[l].du_factors(A[:, l], B[:, l])
            c = -0.5 * K if C[l] is None else C[l]
            out.append(c * (P @ Q.T))
        return out

    def wrap(self, X):
        """Periodic coordinates modulo π (§5); returns a new array."""
        X = np.array(X, dtype=float, copy=True)
        X[:, self.periodic] = np.mod(X[:, self.periodic], np.pi)
        return X
