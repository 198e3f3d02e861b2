"""Partial-contact-posture (PCP) matching, docs/grasping.md (thesis eq. 4.3, 4.4, 4.10, 4.11).

``d_pcp(θ, θ_pcp; s) = Σ_ij s_ij (θ_ij − θ_pcp_ij)²`` with ``s_ij ∈ {0, 1}``: only the selected joints
count.  With ``s`` all ones it is the squared Euclidean distance (phase B of the controller, the SOM's
plain best-match search); with ``s`` from the contacts it is *associative completion*: the best
match supplies the unspecified joints.
"""

from __future__ import annotations

import numpy as np


def check_mask(mask, n_features: int) -> np.ndarray:
    """The selection ``s`` as a float 0/1 vector of length ``n_features`` (None = all joints)."""
    if mask is None:
        return np.ones(n_features)
    s = np.asarray(mask)
    if s.shape != (n_features,):
        raise ValueError(f"PCP mask has shape {s.shape}; it needs one 0/1 entry per joint ({n_features},)")
    if s.dtype != bool and not np.isin(s, (0, 1)).all():
        raise ValueError("PCP mask entries must be 0 or 1 (s_ij ∈ {0, 1}, docs/grasping.md)")
    s = s.astype(float)
    if not s.any():
        raise ValueError("PCP mask selects no joint; a PCP needs at least one contact (docs/grasping.md)")
    return s


def pcp_distances(postures: np.ndarray, theta: np.ndarray, mask=None) -> np.ndarray:
    """``d_pcp`` of ``theta`` (d,) to every row of ``postures`` (M, d) → (M,)."""
    P = np.asarray(postures, dtype=float)
    t = np.asarray(theta, dtype=float).reshape(-1)
    if P.ndim != 2 or P.shape[1] != t.size:
        raise ValueError(f"postures {P.shape} and posture ({t.size},) disagree on the number of joints")
    s = check_mask(mask, t.size)
    return ((P - t) ** 2) @ s


def best_match_index(postures: np.ndarray, theta: np.ndarray, mask=None) -> int:
    """``argmin_k d_pcp(postures_k, theta; s)`` (thesis eq. 4.4 / 4.11); ties go to the lowest index."""
    return int(np.argmin(pcp_distances(postures, theta, mask)))
