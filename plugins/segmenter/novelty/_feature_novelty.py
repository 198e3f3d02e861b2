"""How far a window's classifier features lie from every training window (docs/segmentation.md,
"Feature novelty" under clm_minirocket_novelty).

A classifier can be confident on motion it never saw; the distance of the window's features to
the training windows' is a check that does not ask the classifier.  The features are
standardised per feature (std floored at :data:`SCALE_FLOOR`) and compressed to the
:data:`COMPONENTS` leading principal directions of the training windows; a window's distance to a
training window is measured within that subspace plus the window's own distance from the
subspace (what the training windows never varied in counts fully).  Its *distance* is the mean
over its :data:`NEIGHBOURS` nearest training windows; its *novelty* is the robust z-score of that
distance against the training windows' own distances, each measured leaving out the windows of
its own training segment (median and 1.4826 · median absolute deviation; documented choices).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse.linalg import svds

COMPONENTS = 20  # principal directions of the training windows' features kept
NEIGHBOURS = 5  # nearest training windows a distance is averaged over
SCALE_FLOOR = 1e-2  # per-feature standard deviations below this count as this much
MAD_TO_STD = 1.4826  # the median absolute deviation of a normal distribution, in standard deviations
ARRAYS = ("mean", "scale", "basis", "bank", "reference")


@dataclass(frozen=True)
class FeatureNovelty:
    """Fitted on training features: ``mean``, ``scale`` (F,); ``basis`` (q, F); ``bank`` (n, q) the
    training windows in the subspace; ``reference`` (2,) = median and spread of their own distances."""

    mean: np.ndarray
    scale: np.ndarray
    basis: np.ndarray
    bank: np.ndarray
    reference: np.ndarray

    @classmethod
    def fit(cls, features: np.ndarray, segments: np.ndarray) -> FeatureNovelty:
        """From training windows' features (n, F) and the training segment each came from (n,)."""
        F = np.asarray(features, dtype=float)
        segments = np.asarray(segments)
        if len(np.unique(segments)) < 2:
            raise ValueError("the feature novelty needs training windows from at least 2 segments")
        mean = F.mean(axis=0)
        scale = np.maximum(F.std(axis=0), SCALE_FLOOR)
        Z = (F - mean) / scale
        basis = _leading_directions(Z, min(COMPONENTS, len(Z) - 1))
        bank = Z @ basis.T
        residual = np.linalg.norm(Z - bank @ basis, axis=1)
        d2 = _squared(bank, bank) + residual[:, None] ** 2
        d2[segments[:, None] == segments[None]] = np.inf  # leave the window's own segment out
        own = _nearest_mean(d2)
        finite = own[np.isfinite(own)]
        median = np.median(finite)
        spread = max(MAD_TO_STD * np.median(np.abs(finite - median)), 1e-12 * max(median, 1.0))
        return cls(mean, scale, basis, bank, np.array([median, spread]))

    def novelty(self, features: np.ndarray) -> np.ndarray:
        """(N,) robust z-scores of the windows' distances (N, F features) to the training windows."""
        Z = (np.asarray(features, dtype=float) - self.mean) / self.scale
        G = Z @ self.basis.T
        residual = np.linalg.norm(Z - G @ self.basis, axis=1)
        distance = _nearest_mean(_squared(G, self.bank) + residual[:, None] ** 2)
        return (distance - self.reference[0]) / self.reference[1]

    def arrays(self, prefix: str) -> dict[str, np.ndarray]:
        return {prefix + k: getattr(self, k) for k in ARRAYS}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], prefix: str, n_features: int) -> FeatureNovelty:
        """The inverse of :meth:`arrays`; ValueError when the arrays do not fit together."""
        mean, scale, basis, bank, reference = (arrays[prefix + k] for k in ARRAYS)
        q = basis.shape[0] if basis.ndim == 2 else -1
        shapes = {"mean": (n_features,), "scale": (n_features,), "basis": (q, n_features), "reference": (2,)}
        for name, shape in shapes.items():
            a = arrays[prefix + name]
            if a.shape != shape or a.dtype.kind != "f" or not np.isfinite(a).all():
                raise ValueError(
                    f"'{prefix}{name}' must be a finite float array of shape {shape}, got {a.dtype} {a.shape}"
                )
        if not (1 <= q and bank.ndim == 2 and bank.shape[1] == q and len(bank) >= 2 and bank.dtype.kind == "f"):
            raise ValueError(f"'{prefix}bank' must be a float array of at least 2 rows and {q} columns")
        if (scale <= 0).any() or reference[1] <= 0 or not np.isfinite(bank).all():
            raise ValueError("feature novelty scales must be positive and its training windows finite")
        return cls(mean, scale, basis, bank, reference)


def _leading_directions(Z: np.ndarray, q: int) -> np.ndarray:
    """The ``q`` leading right singular vectors of ``Z`` (q, F).  Only their span matters here, so
    a truncated SVD (ARPACK from a fixed start vector: deterministic) stands in for the full one —
    the same subspace to rounding, about 10× faster on a few thousand windows of 10 000 features."""
    if min(Z.shape) <= q + 1:
        return np.linalg.svd(Z, full_matrices=False)[2][:q]
    size = min(Z.shape)
    _, values, vt = svds(Z, k=q, v0=np.full(size, size**-0.5), tol=0)
    return vt[np.argsort(values)[::-1]]


def _squared(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Squared Euclidean distances (len(A), len(B))."""
    return np.maximum((A * A).sum(axis=1)[:, None] + (B * B).sum(axis=1)[None] - 2.0 * A @ B.T, 0.0)


def _nearest_mean(d2: np.ndarray) -> np.ndarray:
    """Per row, the mean distance to its :data:`NEIGHBOURS` nearest columns (fewer if there are fewer)."""
    k = min(NEIGHBOURS, d2.shape[1])
    return np.sqrt(np.partition(d2, k - 1, axis=1)[:, :k]).mean(axis=1)


def distance_weight(novelty: np.ndarray, limit: float | None) -> np.ndarray:
    """(N,) weights in (0, 1]: 1 up to z-score ``limit``, then ``exp(−(z − limit))`` (documented
    choice: a frame one spread beyond the limit keeps 37 % of its evidence); all 1 for ``limit`` None."""
    z = np.asarray(novelty, dtype=float)
    if limit is None:
        return np.ones(len(z))
    return np.exp(-np.maximum(0.0, np.nan_to_num(z, nan=0.0) - float(limit)))
