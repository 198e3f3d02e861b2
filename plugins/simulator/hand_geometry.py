"""Kinematic skeletons of the three simulated hands, built from documented segment parameters.

Joint names, limits and couplings come from :mod:`handflow.plugins.hands.joints` (the single joint table);
this module adds only geometry: where each joint sits, its axis, and the capsule of the segment it
moves.  :mod:`handflow.plugins.simulator.urdf` turns a :class:`HandSkeleton` into URDF text.

Palm frame ``P`` (right hand, thesis 3.2 sign conventions as in ``handflow.plugins.hands.joints``): origin at
the wrist centre, ``+z`` along the fingers, ``+x`` towards the thumb (radial), ``-y`` palmar (the
side the fingers flex to).  Hence flexion axes are ``+x``; index/middle spread axes ``-y`` (positive
towards the little finger), ring/little ``+y`` (positive towards the thumb); wrist pitch ``+x``;
wrist yaw ``+y`` (positive = radial deviation); palm arch / LFJ5 an axis in the palm plane tilted
``PALM_ARCH_TILT`` from ``+z`` (positive moves the little-finger metacarpal palmar).

Thumb base (docs/glove.md): the thumb frame ``T`` has ``x_T = x_P`` (radial),
``y_T = z_P`` (along the fingers), ``z_T = -y_P`` (palmar).  ShadowHand-like and Gifu-like thumbs
realise ``T · R_z(45°) · R_x(Θ0) · R_y(-Θ1)`` with the thumb along the rotated ``x`` axis
(Θ0 = THJ5 / TH_J1, Θ1 = THJ4 / TH_J2, Θ1 > 0 moves the thumb palmar); the human thumb realises
the direction ``(sin α cos β, cos α, sin α sin β)`` in ``T`` as ``R_y(-β) R_z(-α) e_y``
(α = ``th_abduction``, β = ``th_roll``).  With these choices the three equations of the spec hold
exactly, so a mapped ShadowHand thumb points where the human thumb points.

Documented choice: finger-to-finger self-collision is off (pybullet's default for one multibody);
fingers collide with scene objects only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from handflow.plugins.hands.joints import HAND_MODELS, HandModel

PALM_ARCH_TILT = np.deg2rad(20.0)
"""Tilt of the palm-arch / LFJ5 axis from the palm's long axis towards the little finger."""

_X, _Y, _Z = np.eye(3)
_T_FRAME = Rotation.from_euler("x", 90, degrees=True)  # thumb frame T in the palm frame


@dataclass(frozen=True)
class JointGeom:
    """A hinge joint and the capsule segment it moves.

    ``origin``/``rotation`` place the joint frame in the parent link frame; ``axis`` is expressed in
    the joint frame; the child capsule (``length``, ``radius``) runs along the joint frame's ``+z``.
    ``length == 0`` makes a massless-looking connector without collision (two joints at one point).
    """

    name: str
    parent: str
    child: str
    origin: tuple[float, float, float]
    axis: tuple[float, float, float]
    length: float
    radius: float
    rotation: Rotation = field(default_factory=Rotation.identity)
    lower: float = 0.0
    upper: float = 0.0
    max_torque: float = 0.5


@dataclass(frozen=True)
class HandSkeleton:
    """Base link + palm box + ordered hinge joints of one hand (joint order = URDF link order)."""

    model: HandModel
    base: str
    palm_size: tuple[float, float, float]
    joints: tuple[JointGeom, ...]
    palm_link: str = "palm"


@dataclass(frozen=True)
class FingerParams:
    """Segment lengths (proximal, middle, distal) in metres, capsule radius and knuckle position (x, z) in P."""

    lengths: tuple[float, float, float]
    radius: float
    knuckle: tuple[float, float]


@dataclass(frozen=True)
class ThumbParams:
    """Thumb base position in P, segment lengths (metacarpal, proximal, distal), radius."""

    base: tuple[float, float, float]
    lengths: tuple[float, float, float]
    radius: float


@dataclass(frozen=True)
class HandParams:
    """All documented dimensions of one hand (metres)."""

    palm_size: tuple[float, float, float]  # width (x), thickness (y), length (z)
    fingers: dict[str, FingerParams]
    thumb: ThumbParams
    wrist: bool
    lf_metacarpal_base: tuple[float, float] | None = None  # (x, z) of the palm-arch joint
    finger_torque: float = 0.6
    thumb_torque: float = 1.0
    wrist_torque: float = 6.0


SHADOW_PARAMS = HandParams(
    palm_size=(0.088, 0.022, 0.095),
    fingers={
        "FF": FingerParams((0.045, 0.025, 0.026), 0.0095, (0.033, 0.095)),
        "MF": FingerParams((0.045, 0.025, 0.026), 0.0095, (0.011, 0.099)),
        "RF": FingerParams((0.045, 0.025, 0.026), 0.0095, (-0.011, 0.095)),
        "LF": FingerParams((0.045, 0.025, 0.026), 0.0095, (-0.033, 0.086)),
    },
    thumb=ThumbParams((0.034, -0.008, 0.029), (0.038, 0.032, 0.0275), 0.011),
    wrist=True,
    lf_metacarpal_base=(-0.022, 0.02),
)
"""ShadowHand-like dimensions (public ShadowHand kinematics, rounded)."""

HUMAN_PARAMS = HandParams(
    palm_size=(0.084, 0.026, 0.095),
    fingers={
        "ff": FingerParams((0.044, 0.027, 0.022), 0.0090, (0.031, 0.095)),
        "mf": FingerParams((0.048, 0.030, 0.023), 0.0090, (0.010, 0.098)),
        "rf": FingerParams((0.045, 0.029, 0.023), 0.0085, (-0.011, 0.094)),
        "lf": FingerParams((0.035, 0.020, 0.020), 0.0080, (-0.031, 0.085)),
    },
    thumb=ThumbParams((0.032, -0.010, 0.025), (0.040, 0.032, 0.026), 0.0105),
    wrist=True,
    lf_metacarpal_base=(-0.020, 0.02),
)
"""Adult human hand proportions (segment lengths of an average male hand, rounded)."""

GIFU_PARAMS = HandParams(
    palm_size=(0.100, 0.028, 0.100),
    fingers={
        "FF": FingerParams((0.050, 0.030, 0.028), 0.0105, (0.037, 0.100)),
        "MF": FingerParams((0.050, 0.030, 0.028), 0.0105, (0.012, 0.104)),
        "RF": FingerParams((0.050, 0.030, 0.028), 0.0105, (-0.012, 0.100)),
        "LF": FingerParams((0.050, 0.030, 0.028), 0.0105, (-0.037, 0.094)),
    },
    thumb=ThumbParams((0.040, -0.010, 0.030), (0.040, 0.035, 0.030), 0.0115),
    wrist=False,
)
"""Gifu-like dimensions: slightly larger than the ShadowHand (thesis 3.1.2), no wrist, no palm joint."""

HAND_PARAMS = {"human": HUMAN_PARAMS, "shadow": SHADOW_PARAMS, "gifu": GIFU_PARAMS}


def _limits(model: HandModel, name: str) -> tuple[float, float]:
    j = model.joints[model.index(name)]
    return j.lower, j.upper


class _Builder:
    """Collects :class:`JointGeom` entries, reading limits from the hand's joint table."""

    def __init__(self, model: HandModel) -> None:
        self.model = model
        self.joints: list[JointGeom] = []

    def add(
        self,
        name: str,
        parent: str,
        child: str,
        origin,
        axis,
        length: float,
        radius: float,
        rotation: Rotation | None = None,
        torque: float = 0.5,
    ) -> str:
        lo, hi = _limits(self.model, name)
        self.joints.append(
            JointGeom(
                name=name,
                parent=parent,
                child=child,
                origin=tuple(float(v) for v in origin),
                axis=tuple(float(v) for v in axis),
                length=length,
                radius=radius,
                rotation=rotation or Rotation.identity(),
                lower=lo,
                upper=hi,
                max_torque=torque,
            )
        )
        return child


def _finger(
    b: _Builder,
    parent: str,
    prefix: str,
    names: tuple[str, str, str, str],
    fp: FingerParams,
    origin,
    spread_axis,
    torque: float,
) -> None:
    """Spread + MCP at the knuckle, then PIP and DIP along the finger (capsules along +z)."""
    spread, mcp, pip, dip = names
    l1, l2, l3 = fp.lengths
    b.add(spread, parent, f"{prefix}_knuckle", origin, spread_axis, 0.0, fp.radius, torque=torque)
    b.add(mcp, f"{prefix}_knuckle", f"{prefix}_proximal", (0, 0, 0), _X, l1, fp.radius, torque=torque)
    b.add(pip, f"{prefix}_proximal", f"{prefix}_middle", (0, 0, l1), _X, l2, fp.radius, torque=torque)
    b.add(dip, f"{prefix}_middle", f"{prefix}_distal", (0, 0, l2), _X, l3, fp.radius * 0.9, torque=torque)


def _finger_names(model: HandModel, prefix: str) -> tuple[str, str, str, str]:
    """The four joint names of one finger in kinematic order (spread, MCP, PIP, DIP)."""
    if model.name == "human":
        return tuple(f"{prefix}_{k}" for k in ("spread", "mcp", "pip", "dip"))  # type: ignore[return-value]
    if model.name == "shadow":
        return tuple(f"{prefix}J{k}" for k in (4, 3, 2, 1))  # type: ignore[return-value]
    return tuple(f"{prefix}_J{k}" for k in (1, 2, 3, 4))  # type: ignore[return-value]


def _robot_thumb(b: _Builder, tp: ThumbParams, names: tuple[str, ...], torque: float) -> None:
    """ShadowHand/Gifu thumb: Θ0 about the fixed axis, Θ1 about the rotated -y axis, then flexion joints.

    The thumb segments run along local +z; the base frame is ``T·R_z(45°)·R_y(90°)`` so that the
    spec's ``x`` (thumb direction) is the capsule axis: Θ0 about local ``+z``, Θ1 about local ``-y``.
    """
    base = _T_FRAME * Rotation.from_euler("z", 45, degrees=True) * Rotation.from_euler("y", 90, degrees=True)
    l1, l2, l3 = tp.lengths
    th0, th1, *rest = names
    b.add(th0, "palm", "TH_base", tp.base, _Z, 0.0, tp.radius, rotation=base, torque=torque)
    b.add(th1, "TH_base", "TH_metacarpal", (0, 0, 0), -_Y, l1, tp.radius, torque=torque)
    _thumb_fingers(b, rest, (l1, l2, l3), tp.radius, torque)


def _human_thumb(b: _Builder, tp: ThumbParams, torque: float) -> None:
    """Human thumb: roll β about ``-y_T``, abduction α about the rolled ``-z_T``; segments along ``y_T``.

    Base frame ``T·R_x(-90°)`` makes ``y_T`` the capsule axis (+z): β about local ``-z``, α about ``+y``.
    """
    base = _T_FRAME * Rotation.from_euler("x", -90, degrees=True)
    l1, l2, l3 = tp.lengths
    b.add("th_roll", "palm", "th_base", tp.base, -_Z, 0.0, tp.radius, rotation=base, torque=torque)
    b.add("th_abduction", "th_base", "th_metacarpal", (0, 0, 0), _Y, l1, tp.radius, torque=torque)
    _thumb_fingers(b, ("th_mcp_side", "th_mcp", "th_ip"), (l1, l2, l3), tp.radius, torque, prefix="th")


THUMB_FLEX_AXIS = -_Y
"""Thumb MCP/IP flexion axis in the thumb segment frame (closes the pad towards the fingers; chosen so
flexing the opposed thumb moves its tip towards the middle fingertip, checked in the tests)."""
THUMB_SIDE_AXIS = _X
"""Sideways (THJ3 / th_mcp_side) axis in the thumb segment frame, orthogonal to flexion."""


def _thumb_fingers(b: _Builder, names, lengths, radius: float, torque: float, prefix: str = "TH") -> None:
    """Remaining thumb joints after the base: optional sideways joint, then MCP and IP flexion."""
    l1, l2, l3 = lengths
    parent = f"{prefix}_metacarpal"
    if len(names) == 3:
        side, mcp, ip = names
        parent = b.add(side, parent, f"{prefix}_hub", (0, 0, l1), THUMB_SIDE_AXIS, 0.0, radius, torque=torque)
        b.add(mcp, parent, f"{prefix}_proximal", (0, 0, 0), THUMB_FLEX_AXIS, l2, radius, torque=torque)
    else:
        mcp, ip = names
        b.add(mcp, parent, f"{prefix}_proximal", (0, 0, l1), THUMB_FLEX_AXIS, l2, radius, torque=torque)
    b.add(ip, f"{prefix}_proximal", f"{prefix}_distal", (0, 0, l2), THUMB_FLEX_AXIS, l3, radius * 0.9, torque=torque)


def build_skeleton(hand: str, params: HandParams | None = None) -> HandSkeleton:
    """The skeleton of hand ``human`` | ``shadow`` | ``gifu`` (optionally with other dimensions)."""
    if hand not in HAND_MODELS:
        raise ValueError(f"unknown hand '{hand}'; choose one of {', '.join(HAND_MODELS)}")
    model = HAND_MODELS[hand]
    hp = params or HAND_PARAMS[hand]
    b = _Builder(model)
    if hp.wrist:
        pitch, yaw = ("WRJ1", "WRJ2") if hand == "shadow" else ("wrist_pitch", "wrist_yaw")
        b.add(yaw, "forearm", "wrist", (0, 0, 0), _Y, 0.0, 0.02, torque=hp.wrist_torque)
        b.add(pitch, "wrist", "palm", (0, 0, 0), _X, 0.0, 0.02, torque=hp.wrist_torque)
    if hand == "shadow":
        _robot_thumb(b, hp.thumb, ("THJ5", "THJ4", "THJ3", "THJ2", "THJ1"), hp.thumb_torque)
    elif hand == "gifu":
        _robot_thumb(b, hp.thumb, ("TH_J1", "TH_J2", "TH_J3", "TH_J4"), hp.thumb_torque)
    else:
        _human_thumb(b, hp.thumb, hp.thumb_torque)
    prefixes = list(hp.fingers)
    for prefix in prefixes:
        fp = hp.fingers[prefix]
        names = _finger_names(model, prefix)
        spread_axis = -_Y if prefix.lower() in ("ff", "mf") else _Y
        parent, origin = "palm", (fp.knuckle[0], 0.0, fp.knuckle[1])
        if prefix.lower() == "lf" and hp.lf_metacarpal_base is not None:
            arch = "LFJ5" if hand == "shadow" else "palm_arch"
            mx, mz = hp.lf_metacarpal_base
            axis = (-np.sin(PALM_ARCH_TILT), 0.0, np.cos(PALM_ARCH_TILT))
            parent = b.add(
                arch, "palm", f"{prefix}_metacarpal", (mx, 0, mz), axis, 0.0, fp.radius, torque=hp.finger_torque
            )
            origin = (fp.knuckle[0] - mx, 0.0, fp.knuckle[1] - mz)
        _finger(b, parent, prefix, names, fp, origin, spread_axis, hp.finger_torque)
    skeleton = HandSkeleton(
        model=model, base="forearm" if hp.wrist else "palm", palm_size=hp.palm_size, joints=tuple(b.joints)
    )
    missing = set(model.names) - {j.name for j in skeleton.joints}
    if missing:
        raise RuntimeError(f"skeleton of '{hand}' lacks joints {sorted(missing)}")
    return skeleton
