"""Analytic ShadowHand thumb-base mapping α/β ↔ Θ0/Θ1 (docs/glove.md, thesis 3.5).

Both representations place the unit point of the thumb axis at

- human model (abduction α, roll β): ``p = (sin α cos β, cos α, sin α sin β)``;
- ShadowHand (THJ5 = Θ0 about an axis fixed in the palm, THJ4 = Θ1 about a thumb-relative axis):
  ``p = R_z(45°) R_x(Θ0) R_y(−Θ1) e_x`` (:func:`thumb_axis_shadow`; the spec's
  ``R_z(45°) R_x(Θ0) R_y(Θ1)`` with our sign of Θ1, so that Θ1 ≥ 0 over the joint range).

Closed forms are the spec's; the radicands are evaluated in the algebraically equal, cancellation
free form ``½(sin α cos β − cos α)² + sin²α sin²β`` (resp. ``x² + z²``) as a ``hypot``, which keeps
the round trip below 1e-9 rad right up to the singularity.

Singularity: Θ1 = 0 (α = 45°, β = 0) puts the thumb axis on the Θ0 axis; Θ0 then only spins the
thumb.  There ``thumb_to_shadow`` returns Θ0 = ``theta0_at_singularity`` (documented choice: 0,
or pass the previous Θ0 to keep the robot still).  At α = 0 the human roll β is undefined and
``shadow_to_thumb`` returns β = 0.
"""

from __future__ import annotations

import numpy as np

_H = np.sqrt(0.5)


def thumb_to_shadow(alpha, beta, theta0_at_singularity=0.0, eps: float = 1e-12):
    """(α, β) → (Θ0, Θ1), vectorised; Θ1 ∈ [0, π]."""
    alpha, beta = np.asarray(alpha, dtype=float), np.asarray(beta, dtype=float)
    sa, ca, cb, sb = np.sin(alpha), np.cos(alpha), np.cos(beta), np.sin(beta)
    sin0_sin1 = _H * (sa * cb - ca)
    cos0_sin1 = sa * sb
    sin1 = np.hypot(sin0_sin1, cos0_sin1)
    theta1 = np.arctan2(sin1, _H * (ca + sa * cb))
    theta0 = np.where(sin1 > eps, np.arctan2(sin0_sin1, cos0_sin1), theta0_at_singularity)
    return theta0, theta1


def shadow_to_thumb(theta0, theta1):
    """(Θ0, Θ1) → (α, β), vectorised; α ∈ [0, π]."""
    t0, t1 = np.asarray(theta0, dtype=float), np.asarray(theta1, dtype=float)
    s0, c0, s1, c1 = np.sin(t0), np.cos(t0), np.sin(t1), np.cos(t1)
    x = _H * (c1 + s1 * s0)
    y = _H * (c1 - s1 * s0)
    z = c0 * s1
    return np.arctan2(np.hypot(x, z), y), np.arctan2(z, x)


def thumb_axis_human(alpha, beta) -> np.ndarray:
    """Unit point on the thumb axis from (α, β), shape (..., 3)."""
    alpha, beta = np.asarray(alpha, dtype=float), np.asarray(beta, dtype=float)
    return np.stack([np.sin(alpha) * np.cos(beta), np.cos(alpha), np.sin(alpha) * np.sin(beta)], axis=-1)


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i] = r[j, j] = c
    r[i, j], r[j, i] = -s, s
    return r


def thumb_axis_shadow(theta0: float, theta1: float) -> np.ndarray:
    """Unit point on the thumb axis by the rotation-matrix construction R_z(45°) R_x(Θ0) R_y(−Θ1) e_x."""
    return _rot(2, np.pi / 4) @ _rot(0, theta0) @ _rot(1, -theta1) @ np.array([1.0, 0.0, 0.0])
