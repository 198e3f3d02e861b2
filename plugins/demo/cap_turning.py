"""Scripted cap-turning demonstrator: glove-like joint targets for the ShadowHand-like hand (docs/manipulation.md).

One cycle (= one recorded sequence) has the four phases of the thesis (5.1):

A. open the hand and move back towards the little finger (spreads and wrist yaw to the ulnar side);
B. close the fingers to the cap — the closure depends on the radius (:meth:`CapTurningDemonstrator.closure`);
C. rotate the closed hand around the cap towards the thumb (spreads and wrist yaw to the radial side);
D. open again.

Between the four key postures the targets follow cosine easing.  Human-like variation per sequence
(:class:`CycleVariation`, drawn from a seeded generator): phase durations, closure and sweep
amplitudes, small per-joint offsets.  The targets are what a glove operator would command; the
simulator's collision correction decides the recorded posture.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handflow.plugins.hands.joints import SHADOW

FINGERS = ("FF", "MF", "RF", "LF")
PHASES = ("open_back", "close", "rotate", "open")


@dataclass(frozen=True)
class CycleVariation:
    """Per-sequence variation: phase fractions (sum 1), amplitude scales and joint offsets (rad)."""

    fractions: np.ndarray
    closure_scale: float
    sweep_scale: float
    offsets: np.ndarray


@dataclass
class CapTurningDemonstrator:
    """Glove-like target trajectories for turning a cap of radius ``r`` (metres) with the ShadowHand-like hand.

    Documented choices: the closure law ``closure(r) = closure_small + closure_slope·(r − 0.015)``
    (finger flexion per joint, calibrated so the targets lie slightly inside the cap for every
    radius, hence the collision correction); the sweep of the rotation phase uses the finger spread
    joints (±``sweep`` rad, index/middle and ring/little in opposite joint signs so all fingertips
    move towards the thumb) and the wrist yaw; phase fractions ``fractions`` ± ``timing_jitter``;
    phase D releases the cap before opening (:meth:`released`, ``release_fraction`` of phase D).
    """

    closure_small: float = 1.45
    closure_slope: float = -6.0
    open_flex: float = 0.15
    sweep: float = 0.28
    wrist_sweep: float = 0.2
    fractions: tuple[float, float, float, float] = (0.2, 0.25, 0.35, 0.2)
    timing_jitter: float = 0.15
    amplitude_jitter: float = 0.08
    offset_jitter: float = 0.03
    release_fraction: float = 0.5
    release_joints: tuple[str, ...] = tuple(f"{f}J{k}" for f in FINGERS for k in (2, 1))

    def __post_init__(self) -> None:
        if not 0.0 < self.release_fraction < 1.0:
            raise ValueError(f"release_fraction must lie strictly between 0 and 1, got {self.release_fraction}")
        unknown = [n for n in self.release_joints if n not in SHADOW.names]
        if unknown:
            raise ValueError(
                f"release_joints {unknown} are not ShadowHand-like joints; use names of handflow.plugins.hands.joints.SHADOW"
            )

    def closure(self, radius: float) -> float:
        """Commanded flexion (rad) of MCP, middle and distal joints when closing on a cap of ``radius``."""
        return self.closure_small + self.closure_slope * (radius - 0.015)

    def variation(self, rng: np.random.Generator) -> CycleVariation:
        """Draw one sequence's human-like variation."""
        f = np.asarray(self.fractions) * (1 + rng.uniform(-self.timing_jitter, self.timing_jitter, 4))
        return CycleVariation(
            fractions=f / f.sum(),
            closure_scale=1 + rng.uniform(-self.amplitude_jitter, self.amplitude_jitter),
            sweep_scale=1 + rng.uniform(-2, 2) * self.amplitude_jitter,
            offsets=rng.normal(0.0, self.offset_jitter, len(SHADOW)),
        )

    def key_postures(self, radius: float, var: CycleVariation) -> np.ndarray:
        """The four key postures (4, 24) in SHADOW joint order: open-back, closed-back, closed-front, open-front."""
        flex_closed = self.closure(radius) * var.closure_scale
        sweep = self.sweep * var.sweep_scale
        wrist = self.wrist_sweep * var.sweep_scale
        postures = []
        for closed, front in ((False, False), (True, False), (True, True), (False, True)):
            q = {"WRJ1": 0.0, "WRJ2": wrist * (0.4 if front else -1.0), "LFJ5": 0.15 if closed else 0.05}
            direction = -1.0 if front else 1.0  # +: towards the little finger for FF/MF (joint convention)
            for f in FINGERS:
                q[f"{f}J4"] = direction * sweep * (1.0 if f in ("FF", "MF") else -1.0)
                flex = flex_closed if closed else self.open_flex
                q[f"{f}J3"], q[f"{f}J2"], q[f"{f}J1"] = flex, flex, flex
            q.update(
                THJ5=-0.75 if closed else -0.6,
                THJ4=0.9 if closed else 0.55,
                THJ3=0.0,
                THJ2=0.3 if closed else 0.0,
                THJ1=1.5 * var.closure_scale if closed else 0.2,
            )
            postures.append([q[n] for n in SHADOW.names])
        return SHADOW.clip(np.asarray(postures) + var.offsets)

    def released(self, keys: np.ndarray) -> np.ndarray:
        """The release posture inside phase D: the closed-front grip with ``release_joints`` already open.

        Documented choice against the release flick (measured in docs/benchmarks.md): the
        hand first uncurls the middle and distal finger joints, so the fingertips leave the cap
        while the MCP joints, the thumb and the wrist hold still, and only then opens the rest.
        Opening everything at once (or the thumb first) releases the contacts one by one and the
        last squeezing fingertip spins the cap.
        """
        q = keys[2].copy()
        idx = [SHADOW.index(n) for n in self.release_joints]
        q[idx] = keys[3][idx]
        return q

    def targets(self, phase: np.ndarray, radius: float, var: CycleVariation) -> np.ndarray:
        """Targets (n, 24) at cycle phases in [0, 1): eased interpolation through the key postures.

        Phase A moves from the open-front posture (end of the previous cycle) to open-back, B closes,
        C rotates, D opens in two eased halves: the first ``release_fraction`` of D lifts the fingers
        off the cap (:meth:`released`), the rest uncurls them.
        """
        keys = self.key_postures(radius, var)
        release = self.released(keys)
        bounds = np.concatenate([[0.0], np.cumsum(var.fractions)])
        split = bounds[3] + self.release_fraction * (bounds[4] - bounds[3])
        bounds = np.insert(bounds, 4, split)
        start = np.vstack([keys[3], keys[0], keys[1], keys[2], release])  # segment k goes start[k] → end[k]
        end = np.vstack([keys[0], keys[1], keys[2], release, keys[3]])
        phase = np.clip(np.asarray(phase, dtype=float), 0.0, 1.0 - 1e-12)
        k = np.clip(np.searchsorted(bounds, phase, side="right") - 1, 0, 4)
        s = (phase - bounds[k]) / (bounds[k + 1] - bounds[k])
        w = (0.5 - 0.5 * np.cos(np.pi * s))[:, None]
        return start[k] * (1 - w) + end[k] * w

    def phase_names(self, phase: np.ndarray, var: CycleVariation) -> list[str]:
        """Name of the phase (``open_back`` | ``close`` | ``rotate`` | ``open``) at each cycle phase."""
        bounds = np.cumsum(var.fractions)
        return [PHASES[min(int(np.searchsorted(bounds, x, side="right")), 3)] for x in np.atleast_1d(phase)]
