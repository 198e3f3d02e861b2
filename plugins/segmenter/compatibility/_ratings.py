"""Local compatibility ratings of the manifold recognisers (docs/segmentation.md §A).

All functions are vectorised over observations (axis 0) and candidates (axis 1).  Every
documented choice of the spec is a named, swappable function held in a registry:

* :data:`ORDER_RATINGS` — the directed order rating ``H`` (``"cos"`` = ``cos(mod_π δ)``,
  ``"sign"`` = ``sgn(cos(mod_π δ))``).
* history weights: ``h = 1…H`` with the current observation as ``h = 1`` (lag ``h − 1``),
  :func:`history_compatibility`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

OrderRating = Callable[[np.ndarray], np.ndarray]


def order_rating_cos(delta: np.ndarray) -> np.ndarray:
    """``H(δ) = cos(mod_π(δ))``: ≈ +1 small forward step, 0 at π/2, → −1 small backward step."""
    return np.cos(np.mod(delta, np.pi))


def order_rating_sign(delta: np.ndarray) -> np.ndarray:
    """``H_s(δ) = sgn(cos(mod_π(δ)))``: the sampling-rate insensitive step variant."""
    return np.sign(np.cos(np.mod(delta, np.pi)))


ORDER_RATINGS: dict[str, OrderRating] = {"cos": order_rating_cos, "sign": order_rating_sign}


def order_rating(name: str) -> OrderRating:
    """Look up an order rating by name, with an error listing the valid names."""
    try:
        return ORDER_RATINGS[name]
    except KeyError:
        raise ValueError(f"order rating must be one of {sorted(ORDER_RATINGS)}, got {name!r}") from None


def reconstruction_compatibility(errors: np.ndarray) -> np.ndarray:
    """``C_rec = −1 + 2·exp(−e)`` ∈ [−1, 1] from normalised self-reconstruction errors ``e ≥ 0``."""
    return -1.0 + 2.0 * np.exp(-np.asarray(errors, dtype=float))


def order_compatibility(latent_time: np.ndarray, rating: OrderRating = order_rating_cos) -> np.ndarray:
    """``C_ord(t) = H(x̂_t − x̂_{t−1})`` per observation and candidate.

    The first observation has no predecessor; it gets the neutral value 0 (our choice).
    """
    lt = np.asarray(latent_time, dtype=float)
    out = np.zeros_like(lt)
    out[1:] = rating(lt[1:] - lt[:-1])
    return out


def local_compatibility(
    latent_time: np.ndarray, errors: np.ndarray, rating: OrderRating = order_rating_cos
) -> np.ndarray:
    """``C_local = ½ (C_rec + C_ord)`` (docs/segmentation.md)."""
    return 0.5 * (reconstruction_compatibility(errors) + order_compatibility(latent_time, rating))


def history_weights(history: int, gamma: float) -> np.ndarray:
    """Weights ``γ^h``, ``h = 1…H``; entry ``h − 1`` weighs the observation at lag ``h − 1``."""
    if history < 1:
        raise ValueError(f"history length H must be >= 1, got {history}")
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f"discount gamma must lie in [0, 1], got {gamma}")
    return gamma ** np.arange(1, history + 1, dtype=float)


def history_compatibility(c_local: np.ndarray, history: int, gamma: float) -> np.ndarray:
    """``C_his(t) = Σ_h γ^h C_local(t − h + 1) / Σ_h γ^h`` over the H most recent observations.

    Documented choice (docs/segmentation.md): ``h = 1…H`` with the current observation as ``h = 1``.  At the
    start of a stream only the observations that exist are summed (and normalised).
    """
    c = np.asarray(c_local, dtype=float)
    w = history_weights(history, gamma)
    num = np.zeros_like(c)
    den = np.zeros(c.shape[0])
    for lag, wh in enumerate(w[: c.shape[0]]):
        num[lag:] += wh * c[: c.shape[0] - lag]
        den[lag:] += wh
    den = np.where(den > 0, den, 1.0)
    return num / den.reshape((-1,) + (1,) * (c.ndim - 1))


def overall_compatibility(c_rec: np.ndarray, c_his: np.ndarray, lam: float) -> np.ndarray:
    """``C = λ C_rec + (1 − λ) C_his`` ∈ [−1, 1]."""
    if not 0.0 <= lam <= 1.0:
        raise ValueError(f"lambda must lie in [0, 1], got {lam}")
    return lam * c_rec + (1.0 - lam) * c_his
