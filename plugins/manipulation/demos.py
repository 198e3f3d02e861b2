"""Demonstration recordings of ``handflow demo-record`` as training sequences (docs/manipulation.md), read with :mod:`handflow.plugins.demo.loaders`.

Cap turning: one sequence per turning cycle (collision-corrected ShadowHand-like postures) with
its cap radius (converted to cm).  Ball swapping: one sequence per swap cycle (= ball period =
two hand periods, so the periodic latent time covers one ball period, §1 note) of the d = 20
observations (16 Gifu joints, p1, p2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handflow.plugins.demo.loaders import load_ball_demonstrations, load_cap_demonstrations
from handflow.plugins.manifold.validation import InvalidInputError


@dataclass
class Demonstrations:
    """Ordered sequences (list of (n_i, d)), their dimension names, hand and per-sequence radius (cm)."""

    sequences: list[np.ndarray]
    names: list[str]
    hand: str
    task: str
    radii_cm: np.ndarray | None = None


def load_demonstrations(path) -> Demonstrations:
    """Cap or ball demonstrations, whichever the recording holds."""
    try:
        balls = load_ball_demonstrations(path)
    except ValueError as ball_error:
        try:
            cap = load_cap_demonstrations(path)
        except ValueError as cap_error:
            raise InvalidInputError(f"{cap_error} (as ball demonstrations: {ball_error})") from None
        return Demonstrations(
            [postures for _, postures, _ in cap],
            cap[0][2],
            "shadow",
            "cap",
            np.array([round(meta["radius_m"] * 100.0, 6) for meta, _, _ in cap]),
        )
    return Demonstrations([obs for _, obs, _ in balls], balls[0][2], "gifu", "balls")
