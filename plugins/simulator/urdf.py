"""URDF text of a :class:`~handflow.plugins.simulator.hand_geometry.HandSkeleton` (the generator is the single source).

Segments are capsules (pybullet's URDF ``<capsule>``) along the joint frame's ``+z``; the palm is a
box from the wrist to the knuckles; the forearm a box behind the wrist.  Masses follow a uniform
density (``DENSITY``); joint limits, axes and the effort limits (``max_torque``) are written into
the URDF, so pybullet enforces the limits.  :func:`write_urdf` caches the file under a content
hash, so repeated simulations reuse it and a changed generator never reads a stale file.

``urdf_text(skeleton, viewer=True, prefix=...)`` is the robot description for viewers (docs/foxglove.md):
the same links and joints, link names prefixed (two hands in one scene), geometry only from URDF's
standard primitives (a capsule is drawn as a cylinder plus two spheres), no mesh files, no collision
elements.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

import numpy as np

from .hand_geometry import HandSkeleton, build_skeleton

DENSITY = 1100.0
"""Segment density in kg/m³ (about that of a hand; gives ~20–40 g finger segments)."""

COLOURS = {"human": "0.87 0.72 0.60 1", "shadow": "0.25 0.25 0.28 1", "gifu": "0.55 0.57 0.62 1"}
"""RGBA of the hand per model (dark/neutral so the tracker's coloured blobs stand out)."""


def _inertial(mass: float, ixx: float, iyy: float, izz: float, z: float = 0.0) -> str:
    return (
        f'<inertial><origin xyz="0 0 {z:.6f}"/><mass value="{mass:.6f}"/>'
        f'<inertia ixx="{ixx:.3e}" iyy="{iyy:.3e}" izz="{izz:.3e}" ixy="0" ixz="0" iyz="0"/></inertial>'
    )


def _material(name: str, colour: str) -> str:
    return f'<material name="{name}_m"><color rgba="{colour}"/></material>'


def _box_link(name: str, size, centre, colour: str, viewer: bool = False) -> str:
    sx, sy, sz = size
    mass = DENSITY * sx * sy * sz
    shape = f'<origin xyz="{centre[0]:.6f} {centre[1]:.6f} {centre[2]:.6f}"/><geometry><box size="{sx} {sy} {sz}"/></geometry>'
    inertia = _inertial(
        mass, mass * (sy**2 + sz**2) / 12, mass * (sx**2 + sz**2) / 12, mass * (sx**2 + sy**2) / 12, centre[2]
    )
    collision = "" if viewer else f"<collision>{shape}</collision>"
    return f'<link name="{name}">{inertia}<visual>{shape}{_material(name, colour)}</visual>{collision}</link>'


def _capsule_visuals(name: str, length: float, radius: float, colour: str) -> str:
    """A capsule along ``+z`` from 0 to ``length`` as standard URDF primitives: cylinder and two spheres."""
    parts = [
        f'<origin xyz="0 0 {length / 2:.6f}"/><geometry><cylinder radius="{radius:.5f}" length="{length:.5f}"/></geometry>'
    ]
    parts += [f'<origin xyz="0 0 {z:.6f}"/><geometry><sphere radius="{radius:.5f}"/></geometry>' for z in (0.0, length)]
    return "".join(f"<visual>{shape}{_material(name, colour)}</visual>" for shape in parts)


def _capsule_link(name: str, length: float, radius: float, colour: str, viewer: bool = False) -> str:
    if length == 0:  # connector between two joints at one point: no geometry, tiny inertia
        return f'<link name="{name}">{_inertial(0.005, 1e-7, 1e-7, 1e-7)}</link>'
    mass = DENSITY * np.pi * radius**2 * (length + 4 * radius / 3)
    ixx = mass * (3 * radius**2 + length**2) / 12
    inertial = _inertial(mass, ixx, ixx, mass * radius**2 / 2, length / 2)
    if viewer:
        return f'<link name="{name}">{inertial}{_capsule_visuals(name, length, radius, colour)}</link>'
    shape = f'<origin xyz="0 0 {length / 2:.6f}"/><geometry><capsule radius="{radius:.5f}" length="{length:.5f}"/></geometry>'
    return (
        f'<link name="{name}">{inertial}<visual>{shape}{_material(name, colour)}</visual>'
        f"<collision>{shape}</collision></link>"
    )


def urdf_text(skeleton: HandSkeleton, viewer: bool = False, prefix: str = "") -> str:
    """The URDF document of one hand skeleton (for pybullet, or ``viewer``-safe with ``prefix`` on link names)."""
    colour = COLOURS[skeleton.model.name]
    w, t, length = skeleton.palm_size
    palm_link, base = prefix + skeleton.palm_link, prefix + skeleton.base
    palm = _box_link(palm_link, (w, t, length * 0.92), (0, 0, length * 0.46 + 0.004), colour, viewer)
    links = [palm if base == palm_link else _box_link(base, (w * 0.7, t * 1.2, 0.08), (0, 0, -0.05), colour, viewer)]
    joints = []
    for j in skeleton.joints:  # links in joint order: pybullet keeps this order (URDF_MAINTAIN_LINK_ORDER)
        child, parent = prefix + j.child, prefix + j.parent
        links.append(palm if child == palm_link else _capsule_link(child, j.length, j.radius, colour, viewer))
        roll, pitch, yaw = j.rotation.as_euler("xyz")
        joints.append(
            f'<joint name="{prefix}{j.name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{j.origin[0]:.6f} {j.origin[1]:.6f} {j.origin[2]:.6f}" rpy="{roll:.6f} {pitch:.6f} {yaw:.6f}"/>'
            f'<axis xyz="{j.axis[0]:.6f} {j.axis[1]:.6f} {j.axis[2]:.6f}"/>'
            f'<limit lower="{j.lower:.6f}" upper="{j.upper:.6f}" effort="{j.max_torque}" velocity="3.0"/>'
            f'<dynamics damping="0.01" friction="0.0"/></joint>'
        )
    body = "\n".join(links + joints)
    return f'<?xml version="1.0"?>\n<robot name="{skeleton.model.name}_hand">\n{body}\n</robot>\n'


def write_urdf(hand: str, directory: str | os.PathLike | None = None) -> Path:
    """Generate the URDF of ``hand`` into ``directory`` (default: a per-user temp cache) and return its path."""
    text = urdf_text(build_skeleton(hand))
    digest = hashlib.sha1(text.encode()).hexdigest()[:12]
    folder = Path(directory) if directory is not None else Path(tempfile.gettempdir()) / "handflow_urdf"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{hand}_{digest}.urdf"
    if not path.exists():
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        tmp.replace(path)
    return path
