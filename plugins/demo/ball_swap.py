"""Scripted open-loop ball-swapping motion of the Gifu-like hand (docs/manipulation.md, thesis 5.6.2).

The thesis recorded an open-loop controller (Oztop et al. 2006) that moves only the four fingers;
every hand cycle is identical and the balls' response varies.  The thesis does not give the
motion; documented choice (docs/simulator.md "Ball swapping"), tuned on the ``balls`` scene of
:mod:`handflow.plugins.simulator.scenes` (cupped palm in which the two balls can only circle around each
other):

- **rake** — index and middle finger (``rake_fingers``) hook their tips behind the ball lying at
  the finger end on the thumb side (PIP = DIP flexed ``rake_pip``), then close the MCP joint
  (``rake_mcp``): the hooked fingertips sweep towards the wrist just above the palm and drag that
  ball down the thumb side of the palm; the pair turns and the other ball comes up to the finger
  end on the little-finger side;
- **return** — the two fingers unhook (PIP opens) and swing back out above the balls, brushing the
  ball now at the finger end over to the thumb side, then hook in again: the next cycle rakes the
  *other* ball.  One hand cycle is one swap (the pair turns by π), so one ball period spans two
  hand periods, as in the thesis;
- ring and little finger (``hold_fingers``) stay curled (``hold_mcp``, ``hold_pip``) and close the
  cup at the finger end; the thumb stays put (``thumb``).

Every joint follows periodic key frames ``((phase, value), …)`` with cosine easing between them
(:func:`keyframes`), identical every cycle.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from handflow.plugins.hands.joints import GIFU

Keys = tuple[tuple[float, float], ...]
"""Periodic key frames: (phase in [0, 1), joint angle in rad), phases increasing."""


def keyframes(phase, keys: Keys) -> np.ndarray:
    """Periodic cosine-eased interpolation through ``keys`` at ``phase`` (cycle units, any real)."""
    ph = np.array([k[0] for k in keys], dtype=float)
    val = np.array([k[1] for k in keys], dtype=float)
    if ph.size == 0 or np.any(np.diff(ph) <= 0) or ph[0] < 0 or ph[-1] >= 1:
        raise ValueError(f"key frames need strictly increasing phases in [0, 1), got {list(ph)}")
    ph, val = np.r_[ph, ph[0] + 1.0], np.r_[val, val[0]]
    x = np.asarray(phase, dtype=float) % 1.0
    x = np.where(x < ph[0], x + 1.0, x)
    k = np.clip(np.searchsorted(ph, x, side="right") - 1, 0, ph.size - 2)
    s = (x - ph[k]) / (ph[k + 1] - ph[k])
    w = 0.5 - 0.5 * np.cos(np.pi * s)
    return val[k] * (1 - w) + val[k + 1] * w


@dataclass
class BallSwapMotion:
    """Open-loop Gifu-hand targets of one swap cycle as a function of the phase in [0, 1) (see module docstring)."""

    period_s: float = 2.0
    rake_fingers: tuple[str, ...] = ("FF", "MF")
    rake_mcp: Keys = ((0.0, 0.1), (0.35, 1.4), (0.55, 1.4), (0.8, 0.1))
    rake_pip: Keys = ((0.0, 1.4), (0.35, 1.4), (0.5, 0.3), (0.85, 0.3))
    hold_fingers: tuple[str, ...] = ("RF", "LF")
    hold_mcp: float = 1.0
    hold_pip: float = 1.0
    thumb: dict[str, float] = field(default_factory=lambda: {"TH_J1": 0.0, "TH_J2": 0.3, "TH_J3": 0.0, "TH_J4": 0.0})

    def targets(self, phase) -> np.ndarray:
        """Targets (n, 20) in GIFU joint order at cycle phases ``phase`` (DIP commanded equal to PIP)."""
        phase = np.atleast_1d(np.asarray(phase, dtype=float))
        q = np.zeros((phase.size, len(GIFU)))
        mcp, pip = keyframes(phase, self.rake_mcp), keyframes(phase, self.rake_pip)
        for f in self.rake_fingers:
            q[:, GIFU.index(f"{f}_J2")] = mcp
            q[:, GIFU.index(f"{f}_J3")] = q[:, GIFU.index(f"{f}_J4")] = pip
        for f in self.hold_fingers:
            q[:, GIFU.index(f"{f}_J2")] = self.hold_mcp
            q[:, GIFU.index(f"{f}_J3")] = q[:, GIFU.index(f"{f}_J4")] = self.hold_pip
        for name, value in self.thumb.items():
            q[:, GIFU.index(name)] = value
        return GIFU.clip(q)


def run_open_loop_swaps(
    seconds: float,
    seed: int = 0,
    scene_options: dict | None = None,
    motion: BallSwapMotion | None = None,
    every: int = 8,
):
    """Play the scripted motion open loop in the balls scene (physics only, no camera).

    Returns the two balls' palm-plane positions sampled every ``every`` physics steps, shape
    ``(n, 2, 2)``, and the final scene state; used by the swap tests and ``benchmarks/sim.py``.
    """
    from handflow.plugins.simulator.simulation import Simulation

    motion = motion or BallSwapMotion()
    n = int(motion.period_s * 240)
    with Simulation("gifu", "balls", scene_options, seed=seed) as sim:
        sim.set_targets(GIFU.names, motion.targets(0.0)[0])
        sim.step(120)
        pts = []
        for s in range(int(seconds * 240)):
            sim.set_targets(GIFU.names, motion.targets((s % n) / n)[0])
            sim.step(1)
            if s % every == 0:
                pts.append(sim.scene.palm_plane_positions(sim.client))
        return np.array(pts), sim.scene_state()
