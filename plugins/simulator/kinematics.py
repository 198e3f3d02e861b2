"""Forward kinematics of a :class:`~handflow.plugins.simulator.hand_geometry.HandSkeleton` and its TF tree.

A hand's TF tree has one transform per joint, parent link → child link, exactly as URDF defines
it: the joint frame at ``origin``/``rotation`` in the parent, then the rotation by the joint angle
about ``axis``.  The same skeleton generates the URDF (:mod:`handflow.plugins.simulator.urdf`),
so every child frame is a URDF link.  Used by ``simulator.robot_state`` (the human hand model from
its joint angles) and checked against pybullet's link poses in the tests (docs/foxglove.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from handflow.framework.messages import Transforms

from .hand_geometry import HandSkeleton


@dataclass(frozen=True)
class Frames:
    """Transforms ``parents[i]`` → ``children[i]``: ``translations`` (n, 3), ``rotations`` (n, 4) as x, y, z, w."""

    parents: list[str]
    children: list[str]
    translations: np.ndarray
    rotations: np.ndarray


class HandKinematics:
    """``HandKinematics(skeleton).transforms(names, q)`` → the TF tree of the hand at joint angles ``q``."""

    def __init__(self, skeleton: HandSkeleton, prefix: str = "") -> None:
        self.skeleton = skeleton
        joints = skeleton.joints
        self.parents = [prefix + j.parent for j in joints]
        self.children = [prefix + j.child for j in joints]
        self.base = prefix + skeleton.base
        self._origins = np.array([j.origin for j in joints])
        self._fixed = Rotation.concatenate([j.rotation for j in joints])
        axes = np.array([j.axis for j in joints])
        self._axes = axes / np.linalg.norm(axes, axis=1, keepdims=True)
        self._index = {j.name: k for k, j in enumerate(joints)}

    def joint_vector(self, names: Sequence[str], positions) -> np.ndarray:
        """Joint angles in skeleton order from named positions (joints not named stay 0)."""
        q = np.zeros(len(self._index))
        positions = np.asarray(positions, dtype=float).reshape(-1)
        if len(names) != positions.size:
            raise ValueError(f"{len(names)} joint names for {positions.size} positions")
        unknown = [n for n in names if n not in self._index]
        if unknown:
            raise ValueError(f"hand '{self.skeleton.model.name}' has no joint(s) {unknown}")
        q[[self._index[n] for n in names]] = positions
        return q

    def transforms(self, names: Sequence[str], positions) -> Frames:
        """Every joint's parent → child transform at the given joint angles (radians)."""
        q = np.remainder(self.joint_vector(names, positions) + np.pi, 2 * np.pi) - np.pi  # same rotation, any finite q
        rot = self._fixed * Rotation.from_rotvec(self._axes * q[:, None])
        return Frames(list(self.parents), list(self.children), self._origins.copy(), rot.as_quat())

    def link_poses(self, names: Sequence[str], positions) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """World pose (position, quaternion x, y, z, w) of every link with the base link at the origin."""
        frames = self.transforms(names, positions)
        poses = {self.base: (np.zeros(3), Rotation.identity())}
        for parent, child, t, r in zip(frames.parents, frames.children, frames.translations, frames.rotations):
            p_pos, p_rot = poses[parent]  # the skeleton lists every parent before its children
            poses[child] = (p_pos + p_rot.apply(t), p_rot * Rotation.from_quat(r))
        return {link: (pos, rot.as_quat()) for link, (pos, rot) in poses.items()}


def relative_frames(parents: list[str], children: list[str], world: dict[str, tuple[np.ndarray, np.ndarray]]) -> Frames:
    """Parent → child transforms from world poses (position, quaternion) of both frames, vectorised."""
    parent_pos = np.array([world[n][0] for n in parents]).reshape(-1, 3)
    child_pos = np.array([world[n][0] for n in children]).reshape(-1, 3)
    if not parents:
        return Frames([], [], parent_pos, np.zeros((0, 4)))
    inv = Rotation.from_quat([world[n][1] for n in parents]).inv()
    rot = inv * Rotation.from_quat([world[n][1] for n in children])
    return Frames(list(parents), list(children), inv.apply(child_pos - parent_pos).reshape(-1, 3), rot.as_quat())


def transforms_message(frames: Frames, world: str, base: str, position, quaternion) -> Transforms:
    """A Transforms message: ``world`` → ``base`` at the given pose (quaternion x, y, z, w), then the hand's frames."""
    return Transforms(
        parents=[world, *frames.parents],
        children=[base, *frames.children],
        translations=np.vstack([np.asarray(position, float).reshape(1, 3), frames.translations]),
        rotations=np.vstack([np.asarray(quaternion, float).reshape(1, 4), frames.rotations]),
    )
