"""Closed-loop ball-swapping control on a periodic manipulation manifold (docs/manipulation.md; thesis 5.6.3).

1. observe the two (identical) ball positions;
2. partial projection: the observation with ball *a* in the ball-1 slot and *b* in the ball-2
   slot, and the swapped assignment; each is projected with a mask that selects only the ball-1
   dimensions (``mask="ball1"``, the thesis) or both balls (``mask="both"``); the candidate whose
   reconstruction ``f(x̂)`` matches the observed balls best (both balls, assigned as projected)
   gives the phase ``x̂``.  Documented choice: the projection is the exact minimum over a dense
   grid of ``grid_size`` latent phases (f precomputed; the time axis is 1D), which is also what
   makes it cheap on the control path;
   extension (``tolerance`` τ > 0; τ = 0 is the thesis' pure projection): **phase continuity
   gated by the balls**.  Every grid phase whose ball reconstruction error (both balls, either
   assignment) is within τ of the best one is *consistent* with the observation.  If a
   consistent phase lies within ``lag`` (latent units) of ``prior``, the latent of the last
   command, the estimate is ``prior`` itself and the motion goes on unchanged; otherwise the
   estimate jumps to the consistent phase nearest to ``prior``.
   Why: the balls rest while the fingers travel part of each stroke, so over such stretches the
   ball picture is the same for many phases, and the balls trail the commanded fingers by the
   hand's tracking lag (≈ 0.2 latent at one ball period in 4 s) and by how the balls happen to
   respond; the pure projection then returns the start of the stretch every time and a plan
   with k·Δ shorter than the stretch stalls.  A ball pushed back by more than ``lag`` is
   inconsistent with the commanded phase, and the hand repeats the motion from the phase that
   matches the balls.  If even the best phase explains the balls worse than ``max_error``
   (default ∞), the balls are off the manifold (e.g. the resting start configuration) and carry
   no phase information: the commanded phase is kept.  Otherwise the prior never outweighs the
   balls, it only breaks their ties.  ``refractory`` (latent units, default 0 = off): after a jump
   the commanded phase is kept until the hand has advanced that far from the jump — without it,
   balls that still trail the replayed stroke by a bit more than ``lag`` trigger the next jump
   before the stroke has moved them, and the hand can replay the same part of the motion over and
   over (measured after 1 s holds with the camera tracker, docs/benchmarks.md);
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

    def __init__(
        self,
        manifold: ManipulationManifold,
        k: int = 5,
        delta: float = 0.05,
        mask: str = "ball1",
        tolerance: float = 0.0,
        lag: float = 0.5,
        max_error: float = np.inf,
        grid_size: int = 512,
        refractory: float = 0.0,
    ) -> None:
        if manifold.ball_index.size != 4:
            raise ValueError("closed-loop ball control needs a manifold with ball dimensions (p1_x, p1_y, p2_x, p2_y)")
        if mask not in MASKS:
            raise ValueError(f"mask must be one of {MASKS}, got {mask!r}")
        if int(k) < 1:
            raise ValueError(f"k must be >= 1, got {k}")
        if manifold.q != 1:
            raise ValueError(f"closed-loop control needs a 1D (phase) manifold, got {manifold.latent_names}")
        if not (tolerance >= 0 and lag >= 0 and refractory >= 0):
            raise ValueError(f"tolerance, lag and refractory must be >= 0, got {tolerance}, {lag} and {refractory}")
        self.manifold, self.k, self.mask = manifold, int(k), mask
        self.delta = float(delta) * manifold.time_sign  # the demonstrations' direction
        self.slot1, self.slot2 = manifold.ball_index[:2], manifold.ball_index[2:]
        self.clock = LatentClock(*manifold.range(manifold.time_dim), manifold.periodic)
        self.tolerance, self.lag, self.max_error = float(tolerance), float(lag), float(max_error)
        self.refractory, self.jumped_at = float(refractory), None
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

    def _distance(self, prior) -> np.ndarray:
        """Periodic (or plain) distance of every grid phase to the latent ``prior``."""
        d = np.abs(self.grid - float(np.ravel(prior)[self.manifold.time_dim]))
        if self.manifold.periodic:
            span = self.clock.hi - self.clock.lo
            d = np.minimum(np.mod(d, span), span - np.mod(d, span))
        return d

    def _refractory(self, prior) -> bool:
        """Whether the hand has advanced less than ``refractory`` since the last jump."""
        if self.jumped_at is None or self.refractory <= 0:
            return False
        gone = (float(np.ravel(prior)[self.manifold.time_dim]) - self.jumped_at) * np.sign(self.delta)
        if self.manifold.periodic:
            gone = np.mod(gone, self.clock.hi - self.clock.lo)
        return bool(0 <= gone < self.refractory)

    def estimate(self, points, valid, prior=None) -> PhaseEstimate | None:
        """Phase estimate from observed ball positions (n, 2) with validity flags (n,);
        ``prior``: latent of the last command (used when ``tolerance > 0``)."""
        cand = self._candidates(points, valid)
        if cand is None:
            return None
        Y, W, S, swapped = cand
        R2 = (Y[:, None, :] - self.grid_obs[None, :, :]) ** 2  # (c, grid, d)
        if self.tolerance > 0 and prior is not None:
            err = np.einsum("cgd,cd->cg", R2, S)  # both balls
            dist = np.where(err <= err.min() + self.tolerance, self._distance(prior)[None, :], np.inf)
            c, g = np.unravel_index(int(np.argmin(dist)), dist.shape)
            keep = dist[c, g] <= self.lag or err.min() > self.max_error or self._refractory(prior)
            x = np.ravel(prior)[:1].astype(float) if keep else self.grid[g][None]
            if not keep:
                self.jumped_at = float(self.grid[g])
            return PhaseEstimate(x, float(err[c, g]), swapped[c])
        idx = np.argmin(np.einsum("cgd,cd->cg", R2, W), axis=1)
        err = np.einsum("cd,cd->c", R2[np.arange(len(Y)), idx], S)
        best = int(np.argmin(err))
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
