"""First mapping: raw CyberGlove sensors → 24 joints of the human hand model (docs/glove.md, thesis 3.4).

:class:`HumanHandMapping` is vectorised over frames (``map(raw)`` with raw of shape (n, 22) or
(22,)) and combines

1. linear joints ``θ = θ_min + (s − s_min)/(s_max − s_min)·(θ_max − θ_min)``, clipped;
2. thumb abduction α / roll β from the parallelogram (:mod:`.parallelogram`):
   ``α = α_min + (1 − v)(α_max − α_min)``, ``β = β_min + u(β_max − β_min)``;
3. finger spread under the constraint "index and little finger spread equally" with the dynamic
   zero level of :mod:`.zero_abduction` (:meth:`spread`);
4. the unmeasured thumb MCP sideways joint at the profile's default.

``θ_min, θ_max`` default to the human model's joint limits (:data:`handflow.plugins.hands.joints.HUMAN`),
overridable per joint in the profile.  :meth:`inverse` is the exact inverse on the model's image
(used by the emulator's inverse sensor model and by the tests).
"""

from __future__ import annotations

import numpy as np

from handflow.plugins.hands.joints import HUMAN
from handflow.plugins.hands.sensors import N_SENSORS, sensor_index

from .calibration import SPREAD_SENSORS, GloveProfile, SessionCalibration
from .parallelogram import Parallelogram
from .zero_abduction import zero_level

LINEAR_JOINTS = {
    "thumb_mcp": "th_mcp",
    "thumb_ip": "th_ip",
    "index_mcp": "ff_mcp",
    "index_pip": "ff_pip",
    "index_dip": "ff_dip",
    "middle_mcp": "mf_mcp",
    "middle_pip": "mf_pip",
    "middle_dip": "mf_dip",
    "ring_mcp": "rf_mcp",
    "ring_pip": "rf_pip",
    "ring_dip": "rf_dip",
    "little_mcp": "lf_mcp",
    "little_pip": "lf_pip",
    "little_dip": "lf_dip",
    "palm_arch": "palm_arch",
    "wrist_pitch": "wrist_pitch",
    "wrist_yaw": "wrist_yaw",
}
"""Flex sensor → human joint mapped linearly."""

SPREAD_JOINTS = ("ff_spread", "mf_spread", "rf_spread", "lf_spread")


class HumanHandMapping:
    """``HumanHandMapping(profile, calibration).map(raw) -> joints (n, 24)`` in ``HUMAN.names`` order."""

    def __init__(self, profile: GloveProfile, calibration: SessionCalibration) -> None:
        self.profile = profile
        self.calibration = calibration
        self.names = HUMAN.names
        lo, hi = HUMAN.lower.copy(), HUMAN.upper.copy()
        for joint, (a, b) in profile.joint_ranges_deg.items():
            i = HUMAN.index(joint)
            lo[i], hi[i] = np.deg2rad(a), np.deg2rad(b)
        self.theta_min, self.theta_max = lo, hi
        self._lin_s = np.array([sensor_index(s) for s in LINEAR_JOINTS])
        self._lin_j = np.array([HUMAN.index(j) for j in LINEAR_JOINTS.values()])
        self._s_lo, self._s_hi = calibration.lo, calibration.hi
        b1, b2, b3, b4 = calibration.thumb_intercepts
        self.parallelogram = Parallelogram(profile.thumb_m13, profile.thumb_m24, b1, b2, b3, b4)
        self._roll, self._abd = sensor_index("thumb_roll"), sensor_index("thumb_abduction")
        self._ja, self._jb = HUMAN.index("th_abduction"), HUMAN.index("th_roll")
        self._jside = HUMAN.index("th_mcp_side")
        self._spread_s = np.array([sensor_index(s) for s in SPREAD_SENSORS])
        self._spread_nb = np.array([[sensor_index(a), sensor_index(b)] for a, b in SPREAD_SENSORS.values()])
        self._za = [profile.zero_abduction[s] for s in SPREAD_SENSORS]
        self._jspread = np.array([HUMAN.index(j) for j in SPREAD_JOINTS])
        self.phi_min, self.phi_max = np.deg2rad(profile.spread_phi_min_deg), np.deg2rad(profile.spread_phi_max_deg)

    # -- forward ---------------------------------------------------------------------------------
    def map(self, raw) -> np.ndarray:
        raw = np.asarray(raw, dtype=float)
        single = raw.ndim == 1
        s = np.atleast_2d(raw)
        if s.shape[1] != N_SENSORS:
            raise ValueError(f"raw frames need {N_SENSORS} sensor values, got shape {raw.shape}")
        q = np.empty((len(s), len(HUMAN)))
        lo, hi = self._s_lo[self._lin_s], self._s_hi[self._lin_s]
        tmin, tmax = self.theta_min[self._lin_j], self.theta_max[self._lin_j]
        q[:, self._lin_j] = tmin + (s[:, self._lin_s] - lo) / (hi - lo) * (tmax - tmin)
        u, v = self.parallelogram.relative(s[:, self._roll], s[:, self._abd])
        ja, jb = self._ja, self._jb
        q[:, ja] = self.theta_min[ja] + (1.0 - v) * (self.theta_max[ja] - self.theta_min[ja])
        q[:, jb] = self.theta_min[jb] + u * (self.theta_max[jb] - self.theta_min[jb])
        q[:, self._jside] = np.deg2rad(self.profile.th_mcp_side_deg)
        q[:, self._jspread] = self.spread(s)
        q = np.clip(q, self.theta_min, self.theta_max)
        return q[0] if single else q

    def relative_spread(self, s: np.ndarray) -> np.ndarray:
        """x_i = (s0_i − s_i)/(s0_i − s_min_i) of the three spread sensors, shape (n, 3)."""
        x = np.empty((len(s), 3))
        for k, za in enumerate(self._za):
            a, b = s[:, self._spread_nb[k, 0]], s[:, self._spread_nb[k, 1]]
            s0 = zero_level(a, b, za.h, za.lam)
            smin = self._s_lo[self._spread_s[k]]
            x[:, k] = (s0 - s[:, self._spread_s[k]]) / np.maximum(s0 - smin, 1.0)
        return x

    def spread(self, s: np.ndarray) -> np.ndarray:
        """Spread joints (ff, mf, rf, lf) in each finger's sign convention, shape (n, 4).

        Φ = φ_min + γ(φ_max − φ_min) with γ = mean(x); φ_i = Φ·x_i/Σx (equal thirds when
        |Σx| < 1e-6); lateral positions a_FF = Φ/2, a_LF = −Φ/2, a_MF = a_FF − φ_1,
        a_RF = a_LF + φ_3; index/middle positive towards the little finger, ring/little towards
        the thumb, so ff_spread = lf_spread = −Φ/2 (equal spread of index and little)."""
        x = self.relative_spread(s)
        total = x.sum(axis=1)
        phi_tot = self.phi_min + total / 3.0 * (self.phi_max - self.phi_min)
        safe = np.abs(total) > 1e-6
        share = np.where(safe[:, None], x / np.where(safe, total, 1.0)[:, None], 1.0 / 3.0)
        phi = phi_tot[:, None] * share
        a_ff, a_lf = phi_tot / 2, -phi_tot / 2
        return np.stack([-a_ff, -(a_ff - phi[:, 0]), a_lf + phi[:, 2], a_lf], axis=1)

    # -- inverse (synthetic data, tests) ---------------------------------------------------------
    def inverse(self, q) -> np.ndarray:
        """Raw readings that :meth:`map` sends to ``q`` (n, 24), for q inside the limits and with
        equal index/little spread; non-integer, unclipped."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        s = np.zeros((len(q), N_SENSORS))
        lo, hi = self._s_lo[self._lin_s], self._s_hi[self._lin_s]
        tmin, tmax = self.theta_min[self._lin_j], self.theta_max[self._lin_j]
        s[:, self._lin_s] = lo + (q[:, self._lin_j] - tmin) / (tmax - tmin) * (hi - lo)
        ja, jb = self._ja, self._jb
        v = 1.0 - (q[:, ja] - self.theta_min[ja]) / (self.theta_max[ja] - self.theta_min[ja])
        u = (q[:, jb] - self.theta_min[jb]) / (self.theta_max[jb] - self.theta_min[jb])
        s[:, self._roll], s[:, self._abd] = self.parallelogram.reading(u, v)
        sp = q[:, self._jspread]
        phi_tot = -(sp[:, 0] + sp[:, 3])  # Φ/2 each from index and little
        a_ff, a_lf = phi_tot / 2, -phi_tot / 2
        phi = np.stack([a_ff + sp[:, 1], np.zeros(len(q)), sp[:, 2] - a_lf], axis=1)
        phi[:, 1] = phi_tot - phi[:, 0] - phi[:, 2]
        gamma = (phi_tot - self.phi_min) / (self.phi_max - self.phi_min)
        safe = np.abs(phi_tot) > 1e-9
        x = np.where(safe[:, None], 3 * gamma[:, None] * phi / np.where(safe, phi_tot, 1.0)[:, None], gamma[:, None])
        for k, za in enumerate(self._za):
            a, b = s[:, self._spread_nb[k, 0]], s[:, self._spread_nb[k, 1]]
            s0 = zero_level(a, b, za.h, za.lam)
            smin = self._s_lo[self._spread_s[k]]
            s[:, self._spread_s[k]] = s0 - x[:, k] * np.maximum(s0 - smin, 1.0)
        return s
