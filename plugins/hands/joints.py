"""Canonical joint tables of the three hand models (docs/glove.md).

Every hand model is defined ONCE here: joint names in message order, limits in radians and the
coupled joints.  Mapping nodes put these names in every :class:`JointState`; the simulator builds
its URDFs from them.

Sign convention (all three models, thesis 3.2): a positive rotation moves the segment *towards the
inside of the hand*:

- flexion joints (MCP, PIP, DIP, thumb MCP/IP, palm arch, wrist pitch): positive closes the hand
  (flexion), negative is hyper-extension;
- finger spread joints: index and middle positive towards the little finger, ring and little
  positive towards the thumb (so closing the spread of the hand is positive for every finger);
- thumb abduction α is the exception: as in the spec's equations (glove.md "Second mapping",
  thumb direction ``(sin α cos β, cos α, sin α sin β)`` in the thumb frame, ``cos α`` = component
  along the fingers) it is the angle between the thumb and the along-the-fingers axis, so a larger
  α moves the thumb *away* from the index finger (abduction; α = 0 would lay it along the index
  finger); thumb roll β turns that direction out of the palm plane: positive moves the thumb
  palmar (opposition), β = 0 keeps it in the palm plane;
- wrist yaw: positive = radial deviation (towards the thumb);
- robot hands use the same conventions, so joints that correspond copy over unchanged.

Coupling: ShadowHand-like J1/J2 of FF/MF/RF/LF are coupled in the robot (distal follows middle);
Gifu-like DIP equals PIP.  ``HandModel.coupled`` maps the coupled joint to its driver.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

DEG = np.pi / 180.0


@dataclass(frozen=True)
class Joint:
    """One hinge joint: name, limits in radians and a short description."""

    name: str
    lower: float
    upper: float
    description: str = ""


@dataclass(frozen=True)
class HandModel:
    """Ordered joints of a hand model plus joint couplings (coupled joint → driving joint)."""

    name: str
    joints: tuple[Joint, ...]
    coupled: dict[str, str] = field(default_factory=dict)

    @property
    def names(self) -> list[str]:
        return [j.name for j in self.joints]

    @property
    def lower(self) -> np.ndarray:
        return np.array([j.lower for j in self.joints])

    @property
    def upper(self) -> np.ndarray:
        return np.array([j.upper for j in self.joints])

    def index(self, name: str) -> int:
        """Position of joint ``name`` in the model's order (KeyError names the model)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"hand model '{self.name}' has no joint '{name}'") from None

    def clip(self, q: np.ndarray) -> np.ndarray:
        """Clip joint vector(s) ``q`` (…, n_joints) to the joint limits."""
        return np.clip(q, self.lower, self.upper)

    def __len__(self) -> int:
        return len(self.joints)


def _deg(name: str, lo: float, hi: float, description: str = "") -> Joint:
    return Joint(name, lo * DEG, hi * DEG, description)


FINGERS = ("ff", "mf", "rf", "lf")
"""Index (first), middle, ring, little finger prefixes in every table."""


def _human_finger(f: str, full: str) -> tuple[Joint, ...]:
    return (
        _deg(f"{f}_spread", -35, 20, f"{full} spread (see module docstring for the sign)"),
        _deg(f"{f}_mcp", -20, 90, f"{full} MCP flexion"),
        _deg(f"{f}_pip", 0, 110, f"{full} PIP flexion"),
        _deg(f"{f}_dip", 0, 90, f"{full} DIP flexion"),
    )


HUMAN = HandModel(
    "human",
    (
        _deg("wrist_pitch", -70, 70, "wrist flexion (+) / extension (−)"),
        _deg("wrist_yaw", -40, 25, "wrist radial (+) / ulnar (−) deviation"),
        _deg("palm_arch", 0, 45, "palm arch hinge in the palm plane"),
        _deg("th_abduction", 20, 100, "thumb abduction α (α = 45°, β = 0 ⇔ ShadowHand THJ4 = 0)"),
        _deg("th_roll", 0, 90, "thumb roll β (0 = thumb pad facing the index side)"),
        _deg("th_mcp_side", -15, 15, "passive sideways motion of the thumb MCP (not measured)"),
        _deg("th_mcp", -20, 60, "thumb MCP flexion"),
        _deg("th_ip", -20, 90, "thumb IP flexion"),
        *_human_finger("ff", "index"),
        *_human_finger("mf", "middle"),
        *_human_finger("rf", "ring"),
        *_human_finger("lf", "little"),
    ),
)
"""Human hand model (thesis 3.2): 24 hinge joints."""


def _shadow_finger(p: str, full: str) -> tuple[Joint, ...]:
    return (
        _deg(f"{p}J4", -20, 20, f"{full} spread"),
        _deg(f"{p}J3", -15, 90, f"{full} MCP flexion"),
        _deg(f"{p}J2", 0, 90, f"{full} middle flexion (coupled with J1)"),
        _deg(f"{p}J1", 0, 90, f"{full} distal flexion (coupled with J2)"),
    )


SHADOW = HandModel(
    "shadow",
    (
        _deg("WRJ2", -30, 10, "wrist yaw (radial +)"),
        _deg("WRJ1", -40, 28, "wrist pitch (flexion +)"),
        *_shadow_finger("FF", "index"),
        *_shadow_finger("MF", "middle"),
        *_shadow_finger("RF", "ring"),
        _deg("LFJ5", 0, 45, "little-finger metacarpal / palm arch"),
        *_shadow_finger("LF", "little"),
        _deg("THJ5", -60, 60, "thumb base rotation Θ0 (axis fixed in the palm)"),
        _deg("THJ4", 0, 70, "thumb base abduction Θ1 (axis moves with THJ5)"),
        _deg("THJ3", -12, 12, "thumb hub sideways"),
        _deg("THJ2", -40, 40, "thumb middle flexion"),
        _deg("THJ1", -15, 90, "thumb distal flexion"),
    ),
    coupled={f"{p}J1": f"{p}J2" for p in ("FF", "MF", "RF", "LF")},
)
"""ShadowHand-like robot hand: 24 joints (20 DOF; J1/J2 coupled in FF/MF/RF/LF)."""


def _gifu_finger(p: str, full: str) -> tuple[Joint, ...]:
    return (
        _deg(f"{p}_J1", -20, 20, f"{full} spread"),
        _deg(f"{p}_J2", -10, 90, f"{full} MCP flexion"),
        _deg(f"{p}_J3", 0, 90, f"{full} PIP flexion"),
        _deg(f"{p}_J4", 0, 90, f"{full} DIP flexion (= PIP, fixed coupling)"),
    )


GIFU = HandModel(
    "gifu",
    (
        _deg("TH_J1", -60, 60, "thumb base rotation (as ShadowHand THJ5)"),
        _deg("TH_J2", 0, 70, "thumb base abduction (as ShadowHand THJ4)"),
        _deg("TH_J3", -20, 60, "thumb MCP flexion"),
        _deg("TH_J4", -20, 90, "thumb IP flexion"),
        *_gifu_finger("FF", "index"),
        *_gifu_finger("MF", "middle"),
        *_gifu_finger("RF", "ring"),
        *_gifu_finger("LF", "little"),
    ),
    coupled={f"{p}_J4": f"{p}_J3" for p in ("FF", "MF", "RF", "LF")},
)
"""Gifu-like robot hand: 20 joints, 16 DOF (thumb 4; each finger 3 DOF with DIP = PIP)."""

HAND_MODELS: dict[str, HandModel] = {m.name: m for m in (HUMAN, SHADOW, GIFU)}
"""All hand models by name (the ``hand`` field of a JointState)."""
