"""Manifold controllers (docs/manipulation.md): plain controller classes and thin graph nodes.

- :class:`~.open_loop.OpenLoopController` — latent time advances by Δ per step (5.4);
- :class:`~.feedback_init.GraspByNavigation` — grasp by closing along the radius, then turn (5.5);
- :class:`~.closed_loop.ClosedLoopController` — ball swapping by partial projection and a
  k-step plan (5.6.3);
- :class:`~.manifold_file.ManipulationManifold` — a UKR model with named observation dimensions.
"""

from .closed_loop import ClosedLoopController
from .feedback_init import GraspByNavigation
from .manifold_file import BALL_NAMES, ManipulationManifold
from .open_loop import OpenLoopController

__all__ = ["BALL_NAMES", "ClosedLoopController", "GraspByNavigation", "ManipulationManifold", "OpenLoopController"]
