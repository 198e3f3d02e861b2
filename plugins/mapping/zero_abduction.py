"""Dynamic zero-abduction surface of a spread sensor (docs/glove.md, thesis 3.4.4–3.4.5).

A spread sensor's reading at zero spread depends on the flexion readings ``a`` (left finger MCP)
and ``b`` (right finger MCP).  Our documented parametrisation (the thesis' formula is illegible)
has height ``h`` and exactly the six shape effects of the spec, with ``S = 100`` and ``W = 50`` raw
units fixing the scales:

- ridge coordinate ``m = (a + λ1·b)/2``, ``u = m/S``; flex difference across the ridge
  ``d = a − λ1·b − λ3 − λ2·S·u²``
- ``s0(a, b) = h + λ6·u − λ5·S·u² − d²/(λ4²·W)``

λ1 rotation (weight of ``b``: turns the ridge away from ``a = b``), λ2 flex-dependent bow of the
ridge, λ3 sideways shift, λ4 width of the parabola across the ridge, λ5 front/back closure
(curvature along the ridge), λ6 front/back tilt.  ``[1, 0, 0, 1, 0, 0]`` is the symmetric parabola
``h − (a − b)²/W`` in the flex difference.

:func:`fit_zero_abduction` fits ``h, λ`` by least squares with an asymmetric loss (residuals where
the surface lies *below* a sample weigh ``under_weight`` times more — under-estimation causes
finger crossings), then lifts ``h`` so that a fraction ``cover`` of the samples lies on or under
the surface (documented choice: ``cover = 1``, the fit bounds its data).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

S_SCALE = 100.0
W_SCALE = 50.0
DEFAULT_SHAPE = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0)


def _parts(a, b, lam):
    l1, l2, l3, l4, l5, l6 = lam
    u = (np.asarray(a, dtype=float) + l1 * np.asarray(b, dtype=float)) / (2 * S_SCALE)
    d = a - l1 * b - l3 - l2 * S_SCALE * u**2
    return u, d


def zero_level(a, b, h: float, lam) -> np.ndarray:
    """Zero-spread reading ``s0(a, b; h, λ)`` (vectorised over ``a``, ``b``)."""
    l1, l2, l3, l4, l5, l6 = lam
    u, d = _parts(a, b, lam)
    return h + l6 * u - l5 * S_SCALE * u**2 - d**2 / (l4**2 * W_SCALE)


def zero_level_jacobian(a, b, h: float, lam) -> np.ndarray:
    """∂s0/∂(h, λ1…λ6), shape (n, 7) (analytic; checked against finite differences in the tests)."""
    l1, l2, l3, l4, l5, l6 = lam
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    u, d = _parts(a, b, lam)
    k = 2 * d / (l4**2 * W_SCALE)  # −∂s0/∂d
    du1 = b / (2 * S_SCALE)
    dd1 = -b - 2 * l2 * S_SCALE * u * du1
    return np.stack(
        [
            np.ones_like(u),
            l6 * du1 - 2 * l5 * S_SCALE * u * du1 - k * dd1,
            k * S_SCALE * u**2,
            k,
            2 * d**2 / (l4**3 * W_SCALE),
            -S_SCALE * u**2,
            u,
        ],
        axis=-1,
    )


@dataclass
class ZeroAbductionFit:
    """Result of :func:`fit_zero_abduction`: parameters, the lift applied and the residual stats."""

    h: float
    lam: tuple[float, ...]
    lift: float
    n_above: int
    rms: float


def fit_zero_abduction(
    a, b, s, h0: float | None = None, lam0=DEFAULT_SHAPE, under_weight: float = 30.0, cover: float = 1.0
) -> ZeroAbductionFit:
    """Fit the surface to zero-spread samples ``s`` at flex readings ``a``, ``b`` (1-D arrays)."""
    a, b, s = (np.asarray(v, dtype=float).ravel() for v in (a, b, s))
    if not (a.size == b.size == s.size) or a.size < 7:
        raise ValueError(f"need ≥ 7 samples with equal lengths of a, b, s; got {a.size}, {b.size}, {s.size}")
    if not 0 < cover <= 1:
        raise ValueError(f"cover must be in (0, 1], got {cover}")
    w_under = np.sqrt(under_weight)

    def weights(p):
        r = zero_level(a, b, p[0], p[1:]) - s
        return r, np.where(r < 0, w_under, 1.0)

    def fun(p):
        r, w = weights(p)
        return w * r

    def jac(p):
        _, w = weights(p)
        return w[:, None] * zero_level_jacobian(a, b, p[0], p[1:])

    p0 = np.r_[np.max(s) if h0 is None else h0, lam0]
    lower = np.r_[-np.inf, 0.05, -np.inf, -np.inf, 0.05, -np.inf, -np.inf]
    res = least_squares(fun, p0, jac=jac, bounds=(lower, np.inf), x_scale="jac")
    h, lam = float(res.x[0]), tuple(float(v) for v in res.x[1:])
    r = s - zero_level(a, b, h, lam)
    lift = max(0.0, float(np.quantile(r, cover)))
    h += lift
    r -= lift
    return ZeroAbductionFit(h, lam, lift, int((r > 1e-9).sum()), float(np.sqrt(np.mean(r**2))))


def plot_zero_abduction(a, b, s, h: float, lam, title: str = "", path: str | None = None):
    """Scatter of the samples (a, b, s) over the fitted surface; saved to ``path`` if given."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a, b, s = (np.asarray(v, dtype=float) for v in (a, b, s))
    ga, gb = np.meshgrid(np.linspace(a.min(), a.max(), 40), np.linspace(b.min(), b.max(), 40))
    fig = plt.figure(figsize=(6, 5))
    ax = fig.add_subplot(projection="3d")
    ax.plot_surface(ga, gb, zero_level(ga, gb, h, lam), alpha=0.4, cmap="viridis")
    ax.scatter(a, b, s, s=4, c="k")
    ax.set_xlabel("left flex (raw)")
    ax.set_ylabel("right flex (raw)")
    ax.set_zlabel("spread sensor (raw)")
    ax.set_title(title or f"zero-abduction h={h:.0f}, λ={np.round(lam, 2).tolist()}")
    if path:
        fig.savefig(path, dpi=100)
        plt.close(fig)
    return fig
