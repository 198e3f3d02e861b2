"""Latent initialisation (docs/training.md; thesis 2.1.5, 5.3.4, 5.2).

* ``isomap_init``: scikit-learn Isomap; for a periodic time dimension embed into q+1 dimensions,
  pick the 2D sub-space carrying the cycle and map it with ``atan2*``; scale search over the
  non-periodic dimensions; the same search picks the best neighbourhood size K.
* ``equidistant_init``: latent times ``π i / N_σ`` (periodic) or ``i / (N_σ − 1)`` in
  chronological order; other dimensions 0 plus a seeded jitter.
"""

from __future__ import annotations

import warnings
from itertools import combinations

import numpy as np
from sklearn.manifold import Isomap

from .objective import Objective

# Documented choice: scale candidates for the non-periodic dimensions, in units of the kernel
# bandwidth 1/β (t = β · std of the scaled coordinate).
SCALE_GRID = np.geomspace(0.1, 100.0, 31)
# Documented choice: jitter (in bandwidths) that breaks the exact symmetry of constant
# non-time coordinates, whose gradient would otherwise be identically zero.
JITTER = 1e-3
# Documented choice: Isomap's geodesic matrix is N×N; above this many points it is fitted on
# an evenly spaced subset and the other points are mapped with Isomap.transform.
ISOMAP_MAX_POINTS = 2000


def atan2_star(v, u):
    """``atan2*(v, u) = π/2 + ½ atan2(v, u) ∈ [0, π]`` (thesis eq. 5.7)."""
    return np.pi / 2 + 0.5 * np.arctan2(v, u)


def cycle_plane(Z):
    """Pair of embedding columns that carries the cycle.

    Documented choice (the thesis only says "find the sub-space"): the pair whose centred
    points have the smallest coefficient of variation of their radius, i.e. look most like a
    ring.
    """

    def ring_score(pair):
        P = Z[:, pair] - Z[:, pair].mean(axis=0)
        r = np.hypot(P[:, 0], P[:, 1])
        return r.std() / max(r.mean(), 1e-300)

    return min(combinations(range(Z.shape[1]), 2), key=lambda p: ring_score(list(p)))


def _canonical_signs(Z):
    """Flip each component so its largest-magnitude entry is positive (arpack sign ambiguity)."""
    idx = np.abs(Z).argmax(axis=0)
    return Z * np.sign(Z[idx, np.arange(Z.shape[1])])


def spectral_latents(Y, kernel, n_neighbors):
    """Isomap embedding of Y mapped to the latent layout (periodic dims via atan2*)."""
    n_periodic = int(kernel.periodic.sum())
    if n_periodic > 1:
        raise ValueError(
            "isomap init supports at most one periodic latent dimension; use init='equidistant' or give the latents"
        )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # disconnected-graph warnings: sklearn completes it
        iso = Isomap(n_neighbors=n_neighbors, n_components=kernel.q + n_periodic)
        if len(Y) <= ISOMAP_MAX_POINTS:
            Z = iso.fit_transform(Y)
        else:  # geodesics are N×N: embed an evenly spaced subset, map the rest in blocks
            iso.fit(Y[np.linspace(0, len(Y) - 1, ISOMAP_MAX_POINTS).astype(int)])
            Z = np.vstack([iso.transform(Y[a : a + ISOMAP_MAX_POINTS]) for a in range(0, len(Y), ISOMAP_MAX_POINTS)])
    Z = _canonical_signs(Z)
    X = np.empty((Y.shape[0], kernel.q))
    if n_periodic:
        i, j = cycle_plane(Z)
        P = Z[:, [i, j]] - Z[:, [i, j]].mean(axis=0)
        t = int(np.flatnonzero(kernel.periodic)[0])
        X[:, t] = np.mod(atan2_star(P[:, 1], P[:, 0]), np.pi)
        rest = [c for c in range(Z.shape[1]) if c not in (i, j)]
    else:
        rest = list(range(Z.shape[1]))
    free = np.flatnonzero(~kernel.periodic)
    X[:, free] = Z[:, rest]
    return X


def scale_search(X, objective: Objective, grid=SCALE_GRID, sweeps=2):
    """``X_init = diag(s*) X``, ``s* = argmin_s R_cv(diag(s) X)`` over non-periodic dims (§6.3).

    Coordinate-wise grid search (``sweeps`` passes) after centring each dimension to unit std;
    returns the scaled latents and their R_cv.
    """
    X = X.copy()
    free = np.flatnonzero(~objective.kernel.periodic)
    for l in free:
        X[:, l] -= X[:, l].mean()
        X[:, l] /= max(X[:, l].std(), 1e-300)
    base = X.copy()
    best = objective.reconstruction(X, gradient=False)[0]
    for _ in range(sweeps if len(free) > 1 else 1):
        for l in free:
            beta = objective.kernel.kernels[l].beta
            for t in grid:
                trial = X.copy()
                trial[:, l] = base[:, l] * t / beta
                value = objective.reconstruction(trial, gradient=False)[0]
                if value < best:
                    best, X = value, trial
    return X, best


def isomap_init(Y, objective: Objective, neighbors=(10,)):
    """Isomap + atan2* + scale search for every K in ``neighbors``; keeps the lowest R_cv.

    Returns ``(X, info)`` with ``info = {"K": best K, "R_cv": {K: value}}``.
    """
    N = Y.shape[0]
    valid = [int(k) for k in neighbors if 1 <= int(k) < N]
    if not valid:
        raise ValueError(f"isomap needs n_neighbors < number of points ({N}); got {list(neighbors)}")
    results = {}
    for k in valid:
        X0 = spectral_latents(Y, objective.kernel, k)
        results[k] = scale_search(X0, objective)
    best_k = min(results, key=lambda k: results[k][1])
    return results[best_k][0], {"K": best_k, "R_cv": {k: r[1] for k, r in results.items()}}


def equidistant_init(layout, kernel, time_dim, random_state):
    """Equidistant latent times per sequence in chronological order (§6.4, production §2).

    Periodic time: ``π i / N_σ`` (the cycle closes); non-periodic: ``i / (N_σ − 1)``.  Other
    dimensions: 0 plus a jitter of ``1e-3/β`` (seeded) so their gradient is not identically 0.
    """
    if time_dim is None:
        raise ValueError("init='equidistant' needs a time dimension (set time: true on one latent dimension)")
    rng = np.random.default_rng(random_state)
    pos = layout.positions()
    n = layout.counts[layout.index].astype(float)
    X = np.empty((len(pos), kernel.q))
    for l, k in enumerate(kernel.kernels):
        X[:, l] = rng.normal(0.0, JITTER / k.beta, len(pos))
    X[:, time_dim] = np.pi * pos / n if kernel.periodic[time_dim] else pos / np.maximum(n - 1, 1)
    return kernel.wrap(X)
