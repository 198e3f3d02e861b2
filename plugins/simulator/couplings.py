"""Joint couplings the simulated robot hands' controllers enforce on commanded targets.

``handflow.plugins.hands.joints.HandModel.coupled`` names the coupled joint and its driver; a coupling rule
turns the commanded (coupled, driver) targets into the target actually sent to the coupled joint.
Documented choices (both swappable through ``Simulation(coupling=...)``):

- :func:`distal_at_least_middle` — ShadowHand-like J1/J2 (thesis 3.1.1: "the angle of the distal
  joint is larger than or equal to the middle joint angle"): the distal target is raised to the
  middle target when commanded lower;
- :func:`distal_equals_middle` — Gifu-like DIP = PIP (thesis 3.1.2, fixed coupling).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

CouplingRule = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""(commanded coupled targets, driver targets) → coupled targets to actuate."""


def distal_at_least_middle(coupled: np.ndarray, driver: np.ndarray) -> np.ndarray:
    """ShadowHand-like conditional coupling: distal ≥ middle."""
    return np.maximum(coupled, driver)


def distal_equals_middle(coupled: np.ndarray, driver: np.ndarray) -> np.ndarray:
    """Gifu-like fixed coupling: distal = middle (the commanded distal value is ignored)."""
    return np.asarray(driver, dtype=float).copy()


DEFAULT_COUPLING: dict[str, CouplingRule] = {"shadow": distal_at_least_middle, "gifu": distal_equals_middle}
"""Coupling rule per hand model (the human model has no coupled joints)."""
