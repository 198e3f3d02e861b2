"""Synthetic glove data: a hand-motion trajectory through an inverse sensor model (emulator).

:class:`HandMotion` generates smooth, seedable human-model postures (grasp open/close with per-finger
phase lags, thumb opposition, spread, small wrist motion), all inside the joint limits and obeying
the spread constraint (index and little spread equally).  The inverse sensor model is the exact
inverse of the first mapping (:meth:`handflow.plugins.mapping.human.HumanHandMapping.inverse`) for a glove
profile and session calibration, rounded and clamped to the wire range 1…255.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from handflow.plugins.hands.joints import HUMAN
from handflow.plugins.mapping.calibration import DEFAULT_CALIBRATION, DEFAULT_PROFILE, load_calibration, load_profile
from handflow.plugins.mapping.human import HumanHandMapping


class HandMotion:
    """Human-model joint trajectory ``joints(t)``: grasp cycle of ``period_s``, spread and thumb cycles."""

    def __init__(self, period_s: float = 4.0, amplitude: float = 0.8, seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        self.period_s = period_s
        self.amplitude = amplitude
        self.lag = rng.uniform(0.0, 0.15, len(HUMAN))  # per-joint phase lag (fraction of a cycle)
        self._i = {n: i for i, n in enumerate(HUMAN.names)}

    def joints(self, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        lo, hi = HUMAN.lower, HUMAN.upper
        phase = 2 * np.pi * (t[:, None] / self.period_s - self.lag)
        grasp = 0.5 - 0.5 * np.cos(phase)  # 0 open … 1 closed
        mid = 0.5 * (1 - self.amplitude)
        q = lo + (hi - lo) * (mid + self.amplitude * grasp)
        i = self._i
        for name, freq in (("wrist_pitch", 0.37), ("wrist_yaw", 0.23)):
            q[:, i[name]] = 0.3 * np.sin(2 * np.pi * freq * t / self.period_s * 4)
        q[:, i["th_mcp_side"]] = 0.0
        # spread: Φ shrinks as the hand closes; equal shares → ff = lf = −Φ/2, mf = rf = −Φ/6
        phi_lo, phi_hi = np.deg2rad(-8.0), np.deg2rad(50.0)
        spread_wave = 0.5 + 0.5 * np.sin(2 * np.pi * t / (1.7 * self.period_s))
        phi = phi_lo + (phi_hi - phi_lo) * spread_wave * (1 - grasp[:, i["ff_mcp"]])
        q[:, i["ff_spread"]] = q[:, i["lf_spread"]] = -phi / 2
        q[:, i["mf_spread"]] = q[:, i["rf_spread"]] = -phi / 6
        return HUMAN.clip(q)


class SyntheticGlove:
    """Raw frames of a :class:`HandMotion` seen through a glove profile + session calibration."""

    def __init__(
        self,
        motion: HandMotion | None = None,
        profile_path: str | Path = DEFAULT_PROFILE,
        calibration_path: str | Path = DEFAULT_CALIBRATION,
        noise: float = 0.0,
        seed: int = 0,
    ) -> None:
        self.motion = motion or HandMotion(seed=seed)
        self.mapping = HumanHandMapping(load_profile(profile_path), load_calibration(calibration_path))
        self.noise = noise
        self.rng = np.random.default_rng(seed)

    def frames(self, t) -> np.ndarray:
        """Integer raw frames (n, 22) at times ``t`` (seconds)."""
        raw = self.mapping.inverse(self.motion.joints(t))
        if self.noise:
            raw = raw + self.rng.normal(0.0, self.noise, raw.shape)
        return np.clip(np.rint(raw), 1, 255).astype(np.int64)

    def source(self, k: int, t: float) -> np.ndarray:
        """Emulator source signature: the frame at emulator time ``t``."""
        return self.frames(t)[0]
