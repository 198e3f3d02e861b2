"""Scripted open-loop ball-swapping motion of the Gifu-like hand (spec production.md §1, thesis 5.6.2).

The thesis recorded an open-loop controller (Oztop et al. 2006) moving only the four fingers (the
thumb stays put); every hand cycle is identical and the balls' response varies.  Documented choice
of the motion (the thesis does not give it): a periodic two-stroke pattern on the palm-up hand
tilted towards the fingers and sideways towards the little finger —

1. index and middle finger flex and lift the ball lying on the thumb side towards the wrist;
   gravity lets it roll over to the little-finger side;
2. ring and little finger flex and spread towards the thumb, carrying the ball that lies in front
   of them over to the thumb side.

Targets are smooth (raised-cosine bumps over the cycle phase) and identical every cycle.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from plugins.mapping.hands import GIFU


def bump(phase: np.ndarray, centre: float, width: float) -> np.ndarray:
    """Periodic raised-cosine bump in [0, 1] around ``centre`` (cycle units), zero beyond ``width/2``."""
    d = (np.asarray(phase) - centre + 0.5) % 1.0 - 0.5
    return np.where(np.abs(d) < width / 2, 0.5 + 0.5 * np.cos(2 * np.pi * d / width), 0.0)


@dataclass
class BallSwapMotion:
    """Open-loop finger targets of one swap cycle as a function of the phase in [0, 1)."""

    rest_flex: float = 0.6
    lift_flex: float = 0.75
    carry_flex: float = 0.45
    carry_spread: float = 0.3
    lift_centre: float = 0.25
    carry_centre: float = 0.7
    width: float = 0.45
    period_s: float = 2.0

    def targets(self, phase: np.ndarray) -> np.ndarray:
        """Targets (n, 20) in GIFU joint order (coupled DIP equals PIP; thumb fixed)."""
        phase = np.atleast_1d(np.asarray(phase, dtype=float))
        lift = bump(phase, self.lift_centre, self.width)
        carry = bump(phase, self.carry_centre, self.width)
        q = np.zeros((phase.size, len(GIFU)))
        col = {n: k for k, n in enumerate(GIFU.names)}
        for f in ("FF", "MF", "RF", "LF"):
            flex = self.rest_flex + (self.lift_flex * lift if f in ("FF", "MF") else self.carry_flex * carry)
            for j in ("J2", "J3", "J4"):
                q[:, col[f"{f}_{j}"]] = flex
            if f in ("RF", "LF"):
                q[:, col[f"{f}_J1"]] = self.carry_spread * carry
        q[:, col["TH_J2"]] = 0.3
        return GIFU.clip(q)
