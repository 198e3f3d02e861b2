"""Second mapping: human hand model → robot hands (docs/glove.md, thesis 3.5).

ShadowHand-like: every joint copies over (same sign conventions, :mod:`.hands`) except the thumb
base, computed analytically from (α, β) by :func:`handflow.plugins.mapping.thumb.thumb_to_shadow`; results
are clipped to the robot's limits.  Gifu-like (16 DOF): no wrist, palm or thumb sideways joint
(dropped); thumb base as the ShadowHand's; each finger's PIP and DIP are merged into the one
coupled DOF by ``merge`` (documented choice ``"mean"``; ``"pip"`` or ``"max"`` swappable).
"""

from __future__ import annotations

import numpy as np

from handflow.plugins.hands.joints import GIFU, HUMAN, SHADOW, HandModel

from .thumb import thumb_to_shadow

SHADOW_FROM_HUMAN = {
    "WRJ2": "wrist_yaw",
    "WRJ1": "wrist_pitch",
    "LFJ5": "palm_arch",
    "THJ3": "th_mcp_side",
    "THJ2": "th_mcp",
    "THJ1": "th_ip",
    **{
        f"{F}J{k}": f"{f}_{j}"
        for F, f in (("FF", "ff"), ("MF", "mf"), ("RF", "rf"), ("LF", "lf"))
        for k, j in ((4, "spread"), (3, "mcp"), (2, "pip"), (1, "dip"))
    },
}
"""ShadowHand joint ← human joint (copied); THJ5/THJ4 come from the thumb mapping."""

GIFU_FROM_HUMAN = {
    "TH_J3": "th_mcp",
    "TH_J4": "th_ip",
    **{
        f"{F}_J{k}": f"{f}_{j}"
        for F, f in (("FF", "ff"), ("MF", "mf"), ("RF", "rf"), ("LF", "lf"))
        for k, j in ((1, "spread"), (2, "mcp"))
    },
}
"""Gifu joint ← human joint (copied); TH_J1/TH_J2 from the thumb mapping, J3 = J4 = merged PIP/DIP."""

MERGES = {"mean": lambda pip, dip: 0.5 * (pip + dip), "pip": lambda pip, dip: pip, "max": np.maximum}


class RobotHandMapping:
    """Base: ``map(q_human (n, 24) or (24,)) -> q_robot`` in ``model.names`` order, clipped."""

    model: HandModel
    copies: dict[str, str]
    thumb: tuple[str, str]

    def __init__(self, theta0_at_singularity: float = 0.0) -> None:
        self.theta0_at_singularity = theta0_at_singularity
        self._dst = np.array([self.model.index(r) for r in self.copies])
        self._src = np.array([HUMAN.index(h) for h in self.copies.values()])
        self._t0, self._t1 = (self.model.index(n) for n in self.thumb)
        self._a, self._b = HUMAN.index("th_abduction"), HUMAN.index("th_roll")

    def map(self, q_human) -> np.ndarray:
        q = np.asarray(q_human, dtype=float)
        single = q.ndim == 1
        q = np.atleast_2d(q)
        if q.shape[1] != len(HUMAN):
            raise ValueError(f"human joint vectors need {len(HUMAN)} values, got shape {q.shape}")
        out = np.zeros((len(q), len(self.model)))
        out[:, self._dst] = q[:, self._src]
        out[:, self._t0], out[:, self._t1] = thumb_to_shadow(q[:, self._a], q[:, self._b], self.theta0_at_singularity)
        self._extra(q, out)
        out = self.model.clip(out)
        return out[0] if single else out

    def _extra(self, q: np.ndarray, out: np.ndarray) -> None:
        """Joints that are neither copied nor the thumb base."""


class ShadowHandMapping(RobotHandMapping):
    """Human model → ShadowHand-like 24 joints."""

    model = SHADOW
    copies = SHADOW_FROM_HUMAN
    thumb = ("THJ5", "THJ4")


class GifuHandMapping(RobotHandMapping):
    """Human model → Gifu-like hand (20 joints, 16 DOF)."""

    model = GIFU
    copies = GIFU_FROM_HUMAN
    thumb = ("TH_J1", "TH_J2")

    def __init__(self, merge: str = "mean", theta0_at_singularity: float = 0.0) -> None:
        if merge not in MERGES:
            raise ValueError(f"merge must be one of {sorted(MERGES)}, got {merge!r}")
        self.merge = MERGES[merge]
        super().__init__(theta0_at_singularity)
        fingers = ("ff", "mf", "rf", "lf")
        self._pip = np.array([HUMAN.index(f"{f}_pip") for f in fingers])
        self._dip = np.array([HUMAN.index(f"{f}_dip") for f in fingers])
        self._j3 = np.array([GIFU.index(f"{F}_J3") for F in ("FF", "MF", "RF", "LF")])
        self._j4 = np.array([GIFU.index(f"{F}_J4") for F in ("FF", "MF", "RF", "LF")])

    def _extra(self, q: np.ndarray, out: np.ndarray) -> None:
        merged = self.merge(q[:, self._pip], q[:, self._dip])
        out[:, self._j3] = merged
        out[:, self._j4] = merged
