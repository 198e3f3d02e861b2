"""CLM pair compatibilities as bands, and the classifier evidence they are built from
(docs/segmentation.md §B).

* :data:`PAIR_ERRORS` — the error ``ē_ij`` a CLM pair compatibility uses (``"mean"``: mean of
  ``e_k`` over ``k = i…j``, our reading of the illegible thesis formula 6.15; ``"endpoints"``:
  mean of ``e_i`` and ``e_j``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ._ratings import OrderRating, order_rating_sign, reconstruction_compatibility
from ._unwrapping import ORDER_PATHS, _path, bridged_latent

PairError = Callable[[np.ndarray, int], np.ndarray]


# --------------------------------------------------------------------------------------------
# CLM pair compatibilities, stored as bands: band[m, i, k − 1] = f^m(i, i + k), k = 1…B
# --------------------------------------------------------------------------------------------
def pair_error_mean(errors: np.ndarray, width: int) -> np.ndarray:
    """``ē_ij`` = mean of ``e_k`` over ``k = i…j`` (``j = i + 1…i + width``); NaN past the end.

    ``errors`` is (N, M); returns (M, N, width).
    """
    e = np.asarray(errors, dtype=float)
    n, m = e.shape
    cs = np.vstack([np.zeros((1, m)), np.cumsum(e, axis=0)])  # cs[t] = Σ_{k<t} e_k
    out = np.full((m, n, width), np.nan)
    for k in range(1, width + 1):
        if k < n:
            out[:, : n - k, k - 1] = ((cs[k + 1 :] - cs[: n - k]) / (k + 1)).T
    return out


def pair_error_endpoints(errors: np.ndarray, width: int) -> np.ndarray:
    """``ē_ij = ½ (e_i + e_j)``: the cheaper alternative to :func:`pair_error_mean`."""
    e = np.asarray(errors, dtype=float)
    n, m = e.shape
    out = np.full((m, n, width), np.nan)
    for k in range(1, width + 1):
        if k < n:
            out[:, : n - k, k - 1] = (0.5 * (e[: n - k] + e[k:])).T
    return out


def pair_error_max(errors: np.ndarray, width: int) -> np.ndarray:
    """``ē_ij`` = max of ``e_k`` over ``k = i…j``: a pair is only as compatible as the worst-fitting
    observation between them, so a group cannot reach across a stretch the model does not fit."""
    e = np.asarray(errors, dtype=float)
    n, m = e.shape
    out = np.full((m, n, width), np.nan)
    running = e.copy()  # running[i] = max e_{i…i+k}
    for k in range(1, width + 1):
        if k >= n:
            break
        running = np.maximum(running[:-1], e[k:])
        out[:, : n - k, k - 1] = running.T
    return out


PAIR_ERRORS: dict[str, PairError] = {
    "mean": pair_error_mean,
    "endpoints": pair_error_endpoints,
    "max": pair_error_max,
}


def pair_error(name: str) -> PairError:
    try:
        return PAIR_ERRORS[name]
    except KeyError:
        raise ValueError(f"pair error must be one of {sorted(PAIR_ERRORS)}, got {name!r}") from None


def candidate_band(
    latent_time: np.ndarray,
    errors: np.ndarray,
    width: int,
    rating: OrderRating = order_rating_sign,
    mean_error: PairError = pair_error_mean,
    order_path: str = "direct",
    seams: np.ndarray | None = None,
) -> np.ndarray:
    """Banded CLM compatibilities ``f^m_ij = ½ (c_loc_ij + c_sre_ij)`` for ``0 < j − i ≤ width``.

    ``latent_time`` and ``errors`` are (N, M); returns (M, N, width) with
    ``band[m, i, k − 1] = f^m(i, i + k)`` and 0 where ``i + k ≥ N``.  The matrix is symmetric
    with a zero diagonal (docs/segmentation.md), so the band holds all of it.

    ``order_path="direct"`` rates ``x̂_j − x̂_i`` (docs/segmentation.md).  ``"unwrapped"`` (documented choice,
    docs/segmentation.md) rates the *net progress* along the path, the sum of the consecutive
    steps ``i…j`` each wrapped into ``[−π/2, π/2)`` (:func:`unwrapped_latent`), with ``rating``
    applied to it when it is below π/2 in size and its sign otherwise: it equals the direct
    rating while a pair spans less than a quarter period, but still rates a pair spanning more
    than half a period of forward motion as forward (the direct rating calls it backward, which
    broke sub-sampled letters at large H).

    ``seams`` (M,) (unwrapped path only): for an open-stroke candidate (finite seam) a pair whose
    path crosses the seam — the stroke's end running on into its start — is rated −1: a new
    stroke starts there, the pair does not belong to one motion (documented choice; without it
    a letter followed by another that resembles its beginning reads as a repetition of the
    first, docs/segmentation.md).  NaN = periodic motion, repetitions are forward motion.
    """
    lt = np.asarray(latent_time, dtype=float)
    n, m = lt.shape
    if order_path not in ORDER_PATHS:
        raise ValueError(f"order_path must be one of {ORDER_PATHS}, got {order_path!r}")
    bridged = bridged_latent(lt) if order_path == "unwrapped" else None
    path = None if bridged is None else _path(bridged)
    if seams is not None and path is not None and np.isfinite(seams).any():
        open_stroke = np.isfinite(seams)
        phase = np.mod(bridged - np.where(open_stroke, seams, 0.0), np.pi)  # 0 at the stroke's start
    else:
        open_stroke = None
    loc = np.zeros((m, n, width))
    for k in range(1, min(width, n - 1) + 1):
        if path is None:
            loc[:, : n - k, k - 1] = rating(lt[k:] - lt[: n - k]).T
        else:
            d = path[k:] - path[: n - k]
            r = np.where(np.abs(d) < 0.5 * np.pi, rating(d), np.sign(d))
            if open_stroke is not None:
                end = phase[: n - k] + d
                r = np.where(open_stroke & ((end >= np.pi) | (end < 0.0)), -1.0, r)
            loc[:, : n - k, k - 1] = r.T
    ebar = mean_error(errors, width)
    sre = reconstruction_compatibility(np.nan_to_num(ebar, nan=np.inf))
    band = 0.5 * (loc + sre)
    valid = np.isfinite(ebar)
    return np.where(valid, band, 0.0)


def evidence_temperature(scores: np.ndarray) -> float:
    """τ of :func:`score_evidence`: the median over frames of the gap between the best and the
    second-best class score (1 when it is 0 or there is one class)."""
    S = np.asarray(scores, dtype=float)
    if S.ndim != 2 or S.shape[1] < 2:
        return 1.0
    top2 = np.sort(np.where(np.isfinite(S), S, np.nan), axis=1)[:, -2:]
    gap = top2[:, 1] - top2[:, 0]
    gap = gap[np.isfinite(gap)]
    tau = float(np.median(gap)) if gap.size else 0.0
    return tau if tau > 0 else 1.0


def score_evidence(scores: np.ndarray, temperature: float | None = None) -> np.ndarray:
    """Per-frame class evidence in [0, 1] from any classifier's per-class scores (N, M), larger =
    more likely: a softmax over the classes at temperature τ, by default the median over frames of
    the gap between the best and the second-best score (:func:`evidence_temperature`; documented
    choice, docs/segmentation.md: it makes the mapping independent of the scorer's units — ridge
    decision values, negative DTW distances, HMM log-likelihoods — and gives a frame with a median
    gap ≈ 0.73 for its best class against one rival).  A fitted scorer passes the τ of its
    training frames, so a stream is mapped the same way sample by sample."""
    S = np.asarray(scores, dtype=float)
    if S.ndim != 2 or S.shape[1] < 1:
        raise ValueError(f"scores must be (frames, classes), got shape {S.shape}")
    S = np.where(np.isfinite(S), S, np.nanmin(np.where(np.isfinite(S), S, np.nan)) if np.isfinite(S).any() else 0.0)
    if S.shape[1] == 1:
        return np.ones_like(S)
    tau = evidence_temperature(S) if temperature is None else float(temperature)
    z = (S - S.max(axis=1, keepdims=True)) / tau
    e = np.exp(z)
    return e / e.sum(axis=1, keepdims=True)


def null_class_evidence(scores: np.ndarray, threshold: float, temperature: float | None = None) -> np.ndarray:
    """:func:`score_evidence` (N, M + 1) of the classes and a *null class*, the background, that
    scores ``threshold`` on every frame (last column; τ is that of the class scores unless given).
    The null class has the most evidence exactly where the best class scores below ``threshold``,
    so the per-frame winner is the classifier's own decision with rejection at that threshold
    (documented choice, docs/segmentation.md: the CLM over a scorer rejects on the scorer's scale).
    ``−inf``: the null column is 0 (no rejection); ``+inf``: it is 1 (everything rejected)."""
    S = np.asarray(scores, dtype=float)
    tau = evidence_temperature(S) if temperature is None else float(temperature)
    t = float(threshold)
    if np.isinf(t):
        classes = np.zeros_like(S) if t > 0 else score_evidence(S, tau)
        return np.hstack([classes, np.full((len(S), 1), float(t > 0))])
    return score_evidence(np.hstack([S, np.full((len(S), 1), t)]), tau)


def evidence_band(evidence: np.ndarray, width: int, history: int) -> np.ndarray:
    """Banded CLM compatibilities of classifier evidence over M classes: ``f^m_ij = e_im + e_jm − 2/M``
    for ``0 < j − i ≤ history`` (0 beyond, and past the end), laid out as :func:`candidate_band`.

    Documented choice (docs/segmentation.md): two frames support each other in layer m when together
    their evidence for m is above chance (``e_im + e_jm > 2/M``) and repel when it is below.  With a
    baseline of 1 instead of 2/M, a frame whose best class has evidence below ½ (common with 4+
    classes) repels every layer and is left to the background: on BasicMotions that rejected 37 % of
    the frames at background strength 0 and cut the frame accuracy from MiniRocket's 0.91 to 0.61.
    """
    e = np.asarray(evidence, dtype=float)
    n, m = e.shape
    band = np.zeros((m, n, width))
    for k in range(1, min(width, history, n - 1) + 1):
        band[:, : n - k, k - 1] = (e[: n - k] + e[k:] - 2.0 / m).T
    return band


def novelty_weight(errors: np.ndarray, own_errors: np.ndarray, novelty: float, intensity: np.ndarray) -> np.ndarray:
    """Per frame and class (N, M), how far the class models explain the frame, in (0, 1]:
    ``min(1, own / (novelty · error))`` of the best-fitting manifold (errors (N, M), own typical
    errors (M,)) times each class's intensity weight (``intensity`` (N, M), :mod:`..novelty`).
    The first factor is 1 while the error stays within ``1 / novelty`` times the manifold's own
    typical error on its training frames, then falls with the ratio (documented choice,
    docs/segmentation.md: scale-free, and frames the manifolds explain keep the classifier's
    evidence unchanged); the second keeps a class's evidence only where the frame moves as
    vigorously as that class's training frames."""
    E = np.asarray(errors, dtype=float)
    best = np.argmin(E, axis=1)
    error = np.maximum(E[np.arange(len(E)), best], 1e-300)
    weight = np.minimum(1.0, np.asarray(own_errors, dtype=float)[best] / (float(novelty) * error))
    return weight[:, None] * np.asarray(intensity, dtype=float)


def background_band(n: int, width: int, strength: float, radius: int) -> tuple[np.ndarray, float]:
    """Background layer ``f^bg_ij = λ_bg (1 − |i − j| / K_bg)`` for ``|i − j| < K_bg`` (docs/segmentation.md).

    Returns the (N, width) band of off-diagonal entries and the diagonal (self-excitation λ_bg).
    """
    if radius < 1:
        raise ValueError(f"background radius K_bg must be >= 1, got {radius}")
    k = np.arange(1, width + 1, dtype=float)
    row = np.where(k < radius, strength * (1.0 - k / radius), 0.0)
    band = np.tile(row, (n, 1))
    for kk in range(1, width + 1):  # no partner past the end of the sequence
        band[max(n - kk, 0) :, kk - 1] = 0.0
    return band, float(strength)


def thesis_background_strength(n: int) -> float:
    """``λ_bg = 1 − 10/N`` (thesis 6.3.4, defined for N > 10; we use N = 11 below that)."""
    return 1.0 - 10.0 / max(int(n), 11)
