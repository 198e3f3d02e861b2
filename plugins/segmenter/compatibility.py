"""Compatibility formulas of the manifold recognisers (docs/segmentation.md §A and §B).

All functions are vectorised over observations (axis 0) and candidates (axis 1).  Every
documented choice of the spec is a named, swappable function held in a registry:

* :data:`ORDER_RATINGS` — the directed order rating ``H`` (``"cos"`` = ``cos(mod_π δ)``,
  ``"sign"`` = ``sgn(cos(mod_π δ))``).
* :data:`PAIR_ERRORS` — the error ``ē_ij`` a CLM pair compatibility uses (``"mean"``: mean of
  ``e_k`` over ``k = i…j``, our reading of the illegible thesis formula 6.15; ``"endpoints"``:
  mean of ``e_i`` and ``e_j``).
* history weights: ``h = 1…H`` with the current observation as ``h = 1`` (lag ``h − 1``),
  :func:`history_compatibility`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .openset import runs

OrderRating = Callable[[np.ndarray], np.ndarray]
PairError = Callable[[np.ndarray, int], np.ndarray]


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


SPIKE_STEP = 0.25 * np.pi  # observations this far from both ends of their run make a spike
SPIKE_LENGTH = 2  # the longest spike (observations) that is bridged; docs/segmentation.md


def wrapped_step(step: np.ndarray) -> np.ndarray:
    """Latent steps wrapped into ``[−π/2, π/2)`` (latent period π)."""
    return np.mod(step + 0.5 * np.pi, np.pi) - 0.5 * np.pi


def bridged_latent(latent_time: np.ndarray) -> np.ndarray:
    """Latent times (N, …) with every *spike* bridged (axis 0).

    Documented choice (docs/segmentation.md): a spike is a run of up to :data:`SPIKE_LENGTH`
    observations whose projections all lie more than a quarter period (:data:`SPIKE_STEP`) away
    from the observations just before and just after the run, while those two lie less than that
    apart; the run is moved onto the straight line between them.  A projection that lands briefly
    on another branch of the manifold (near a crossing, or at the stroke's seam) would otherwise
    add or remove a whole period of progress.  The first and the last observation are kept.
    """
    lt = np.array(latent_time, dtype=float, copy=True)
    raw = lt.copy()
    n = lt.shape[0]
    for length in range(1, SPIKE_LENGTH + 1):
        if n < length + 2:
            break
        before, after = raw[: n - length - 1], raw[length + 1 :]
        bridge = wrapped_step(after - before)
        spike = np.abs(bridge) < SPIKE_STEP
        for i in range(length):
            here = raw[1 + i : n - length + i]
            spike &= (np.abs(wrapped_step(here - before)) > SPIKE_STEP) & (
                np.abs(wrapped_step(after - here)) > SPIKE_STEP
            )
        for i in range(length):
            lt[1 + i : n - length + i] = np.where(
                spike, np.mod(before + bridge * (i + 1) / (length + 1), np.pi), lt[1 + i : n - length + i]
            )
    return lt


def unwrapped_latent(latent_time: np.ndarray) -> np.ndarray:
    """Latent path: the steps of :func:`bridged_latent`, each wrapped into ``[−π/2, π/2)``, summed
    (axis 0)."""
    return _path(bridged_latent(latent_time))


def _path(bridged: np.ndarray) -> np.ndarray:
    """:func:`unwrapped_latent` of latent times already bridged."""
    steps = wrapped_step(np.diff(bridged, axis=0))
    return np.concatenate([np.zeros((1,) + steps.shape[1:]), np.cumsum(steps, axis=0)])


ORDER_PATHS = ("unwrapped", "direct")


def reject_small_progress(labels: np.ndarray, latent_time: np.ndarray, min_progress: float) -> np.ndarray:
    """Labels (N,) of candidate indices with every segment that moves less than ``min_progress``
    periods forward along its own candidate's latent time set to −1.

    A segment is a maximal run of one label; its progress is the net change of that candidate's
    unwrapped latent path (:func:`unwrapped_latent`, latent period π) from its first to its last
    observation, divided by π.  Documented choice (docs/segmentation.md): a motion is recognised
    only once it has covered a share of its manifold.  A piece of another motion that happens to
    match a short arc of a candidate — a letter written backwards matches short forward arcs of
    other letters — covers little of it, a performed motion covers most of it (or repeats it).
    """
    if min_progress < 0:
        raise ValueError(f"min_progress must be >= 0 periods, got {min_progress}")
    out = np.array(labels, dtype=int, copy=True)
    if min_progress == 0 or out.size == 0:
        return out
    path = unwrapped_latent(latent_time)
    for label, start, stop in runs(out):
        if label >= 0 and (path[stop - 1, label] - path[start, label]) / np.pi < min_progress:
            out[start:stop] = -1
    return out


def reject_poor_fit(
    labels: np.ndarray,
    errors: np.ndarray,
    max_fit_ratio: float | None,
    reversed_errors: np.ndarray | None = None,
) -> np.ndarray:
    """Labels (N,) of candidate indices with every segment whose candidate fits it worse than
    ``max_fit_ratio`` times the best-fitting candidate set to −1 (``None`` = off).

    A segment is a maximal run of one label; a candidate's fit is its mean error over the segment
    (``errors`` (N, M)).  Documented choice (docs/segmentation.md): the CLM weighs fit against
    forward order, so a motion whose own manifold runs backward through it — a letter written
    backwards — goes to another candidate that moves forward but fits it several times worse; a
    recognised motion's candidate is (nearly) the best fit.  ``reversed_errors`` (N, M): the
    errors of the observations with their headings turned round (:mod:`.headings`); the best fit
    is then also sought among the candidates traversed backward.
    """
    out = np.array(labels, dtype=int, copy=True)
    if max_fit_ratio is None or out.size == 0:
        return out
    if not max_fit_ratio >= 1:
        raise ValueError(f"max_fit_ratio must be >= 1 (or None = off), got {max_fit_ratio}")
    E = np.asarray(errors, dtype=float)
    R = None if reversed_errors is None else np.asarray(reversed_errors, dtype=float)
    for label, start, stop in runs(out):
        if label >= 0:
            fit = E[start:stop].mean(axis=0)
            best = fit.min() if R is None else min(fit.min(), R[start:stop].mean(axis=0).min())
            if fit[label] > max_fit_ratio * best:
                out[start:stop] = -1
    return out


def reject_segments(
    labels: np.ndarray,
    latent_time: np.ndarray,
    errors: np.ndarray,
    min_progress: float = 0.0,
    max_fit_ratio: float | None = None,
    open_ends: tuple[bool, bool] = (False, False),
    reversed_errors: np.ndarray | None = None,
) -> np.ndarray:
    """The segment rules applied after the CLM: :func:`reject_poor_fit` (with ``reversed_errors``),
    then :func:`reject_small_progress` (a segment the first rejects takes no part in the second).

    ``open_ends`` (start, end): whether the sequence is cut out of a longer stream there; a segment
    touching an open end is left as it is, since only part of it is in view (documented choice,
    docs/segmentation.md).
    """
    judged = reject_small_progress(
        reject_poor_fit(labels, errors, max_fit_ratio, reversed_errors), latent_time, min_progress
    )
    if not any(open_ends):
        return judged
    out = np.array(labels, dtype=int, copy=True)
    for _, start, stop in runs(out):
        if not ((open_ends[0] and start == 0) or (open_ends[1] and stop == out.size)):
            out[start:stop] = judged[start:stop]
    return out


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
    errors (M,)) times each class's intensity weight (``intensity`` (N, M), :mod:`.intensity`).
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
