"""Open-loop control by latent space navigation (docs/manipulation.md; thesis 5.4).

The sequence parameters (e.g. the radius) are fixed; the latent time advances by ``delta`` per
control step in the demonstrations' direction (:attr:`ManipulationManifold.time_sign`); the
command is the joint part of ``f(x)``.  Speed = ``delta``.
"""

from __future__ import annotations

import numpy as np

from .latent_time import LatentClock
from .manifold_file import ManipulationManifold


class OpenLoopController:
    """``step()`` → ``(x, joint targets)`` along ``x(k) = x0 + k·delta·e_time``."""

    def __init__(self, manifold: ManipulationManifold, latent, delta: float) -> None:
        x = np.asarray(latent, dtype=float).reshape(-1)
        if x.shape != (manifold.q,):
            raise ValueError(
                f"latent start must have {manifold.q} coordinates ({', '.join(manifold.latent_names)}), got {x.size}"
            )
        self.manifold = manifold
        self.delta = float(delta) * manifold.time_sign
        t = manifold.time_dim
        self.x = x.copy()
        self.clock = LatentClock(*manifold.range(t), manifold.periodic, start=x[t])
        self.x[t] = self.clock.value

    @property
    def cycles(self) -> int:
        return self.clock.cycles

    def step(self) -> tuple[np.ndarray, np.ndarray]:
        """Advance one control step; returns the new latent and its joint targets."""
        self.x[self.manifold.time_dim] = self.clock.advance(self.delta)
        return self.x.copy(), self.manifold.posture(self.x)
