"""Closed-loop ball-swapping control on a periodic manipulation manifold (spec production.md §4
"Closed-loop"; thesis 5.6.3).

1. observe the two (identical) ball positions;
2. partial projection: the observation with ball *a* in the ball-1 slot and *b* in the ball-2
   slot, and the swapped assignment; each is projected with a mask that selects only the ball-1
   dimensions (``mask="ball1"``, the thesis) or both balls (``mask="both"``); the candidate whose
   reconstruction ``f(x̂)`` matches the observed balls best (both balls, assigned as projected)
   gives the phase ``x̂``.  Documented choice: the projection is the exact minimum over a dense
   grid of ``grid_size`` latent phases (f precomputed; the time axis is 1D), which is also what
   makes it cheap on the control path;
   extension (``prior_weight`` w > 0, off = the thesis): both the projection and the choice of
   assignment add ``w · d(x, x_prior)²`` (d = periodic distance) to the error, where ``x_prior``
   is the latent of the last command.  Ball positions do not change while the fingers move
   without touching the balls, so the phase is ambiguous along such stretches; the pure
   projection then keeps returning the start of the stretch and a short plan (k·Δ smaller than
   the stretch) stalls; the prior keeps the estimate moving with the commands as long as the
   balls agree, and a pushed-back ball still pulls it back;
3. plan ``x̂ + lΔ``, l = 1…k, along the time dimension;
4. map the plan with f; the hand-posture part is the command sequence;
5. the caller actuates it in order and observes again.

With only one valid ball it is tried in both slots (mask on that slot); with none there is no
estimate (the node's stale-input fail-safe takes over).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .latent_time import LatentClock
from .manifold_file import ManipulationManifold

MASKS = ("ball1", "both")


@dataclass
class PhaseEstimate:
    """Latent ``x`` (q,), ball reconstruction error, and whether the balls were swapped."""

    x: np.ndarray
    error: float
    swapped: bool


class ClosedLoopController:
    """``update(points, valid)`` → planned latents (k, q) and joint targets (k, n_joints)."""

    def __init__(self, manifold: ManipulationManifold, k: int = 5, delta: float = 0.05,
                 mask: str = "ball1", prior_weight: float = 0.0, grid_size: int = 512) -> None:
        if manifold.ball_index.size != 4:
            raise ValueError("closed-loop ball control needs a manifold with ball dimensions "
                             "(p1_x, p1_y, p2_x, p2_y)")
        if mask not in MASKS:
            raise ValueError(f"mask must be one of {MASKS}, got {mask!r}")
        if int(k) < 1:
            raise ValueError(f"k must be >= 1, got {k}")
        if manifold.q != 1:
            raise ValueError(f"closed-loop control needs a 1D (phase) manifold, got "
                             f"{manifold.latent_names}")
        if not prior_weight >= 0:
            raise ValueError(f"prior_weight must be >= 0, got {prior_weight}")
        self.manifold, self.k, self.mask = manifold, int(k), mask
        self.delta = float(delta) * manifold.time_sign      # the demonstrations' direction
        self.slot1, self.slot2 = manifold.ball_index[:2], manifold.ball_index[2:]
        self.clock = LatentClock(*manifold.range(manifold.time_dim), manifold.periodic)
        self.prior_weight = float(prior_weight)
        lo, hi = manifold.range(0)
        self.grid = np.linspace(lo, hi, int(grid_size), endpoint=not manifold.periodic)
        self.grid_obs = manifold.observation(self.grid[:, None])

    def _candidates(self, points, valid):
        """(observations (c, d), masks (c, d), scored dims per candidate, swapped flags)."""
        d = len(self.manifold.names)
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        ok = np.flatnonzero(np.asarray(valid, dtype=bool))
        if ok.size >= 2:
            a, b = pts[ok[0]], pts[ok[1]]
            assignments = [((a, b), False), ((b, a), True)]
        elif ok.size == 1:
            assignments = [((pts[ok[0]], None), False), ((None, pts[ok[0]]), True)]
        else:
            return None
        Y, W, scored, swapped = [], [], [], []
        for (p1, p2), sw in assignments:
            y, w, s = np.zeros(d), np.zeros(d), np.zeros(d)
            for slot, p in ((self.slot1, p1), (self.slot2, p2)):
                if p is not None:
                    y[slot], s[slot] = p, 1.0
            if p1 is not None and p2 is not None:
                w[self.slot1] = 1.0
                if self.mask == "both":
                    w[self.slot2] = 1.0
            else:
                w[:] = s
            Y.append(y), W.append(w), scored.append(s), swapped.append(sw)
        return np.array(Y), np.array(W), np.array(scored), swapped

    def _prior_cost(self, x, prior):
        if prior is None or self.prior_weight == 0:
            return np.zeros_like(x)
        d = np.abs(x - float(np.ravel(prior)[0]))
        if self.manifold.periodic:
            span = self.clock.hi - self.clock.lo
            d = np.minimum(np.mod(d, span), span - np.mod(d, span))
        return self.prior_weight * d * d

    def estimate(self, points, valid, prior=None) -> PhaseEstimate | None:
        """Phase estimate from observed ball positions (n, 2) with validity flags (n,);
        ``prior``: latent of the last command (used when ``prior_weight > 0``)."""
        cand = self._candidates(points, valid)
        if cand is None:
            return None
        Y, W, S, swapped = cand
        R = Y[:, None, :] - self.grid_obs[None, :, :]                 # (c, grid, d)
        penalty = self._prior_cost(self.grid, prior)
        idx = np.argmin(np.einsum("cgd,cd->cg", R * R, W) + penalty, axis=1)
        err = np.einsum("cd,cd->c", R[np.arange(len(Y)), idx] ** 2, S)
        best = int(np.argmin(err + penalty[idx]))
        return PhaseEstimate(self.grid[idx[best]][None], float(err[best]), swapped[best])

    def plan(self, x) -> tuple[np.ndarray, np.ndarray]:
        """Latents ``x + lΔ·e_time`` (k, q), l = 1…k, and their joint targets (k, n_joints)."""
        t = self.manifold.time_dim
        self.clock.value = float(x[t])
        X = np.repeat(np.asarray(x, dtype=float)[None, :], self.k, axis=0)
        X[:, t] = self.clock.ahead(self.delta * np.arange(1, self.k + 1))
        return X, self.manifold.posture(X)

    def update(self, points, valid, prior=None):
        """Estimate and plan; ``None`` when no ball is visible."""
        est = self.estimate(points, valid, prior)
        if est is None:
            return None
        X, targets = self.plan(est.x)
        return est, X, targets
