"""What a 3D viewer needs from a simulated scene: the hand's TF tree, its description, scene objects as markers.

Frame names: the world frame (pybullet's world, ``world`` by default) and the hand's URDF links under
a prefix (``sim/palm``); the description is :func:`~handflow.plugins.simulator.urdf.urdf_text` with
``viewer=True`` and the same prefix, so every TF child frame is one of its links (docs/foxglove.md).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from handflow.framework.messages import Markers, Transforms

from .bullet import pybullet as p
from .kinematics import relative_frames, transforms_message
from .simulation import Simulation

# pybullet visual geometry → (marker kind, scale from pybullet's dimensions)
_SHAPES = {
    p.GEOM_SPHERE: ("sphere", lambda d: [2 * d[0]] * 3),
    p.GEOM_BOX: ("cube", lambda d: list(d[:3])),
    p.GEOM_CYLINDER: ("cylinder", lambda d: [2 * d[1], 2 * d[1], d[0]]),
    p.GEOM_CAPSULE: ("cylinder", lambda d: [2 * d[1], 2 * d[1], d[0] + 2 * d[1]]),
}


def simulated_hand_transforms(sim: Simulation, prefix: str, world: str = "world") -> Transforms:
    """The simulated hand's TF tree from pybullet's link poses (after physics, collisions included)."""
    poses = {prefix + name: pose for name, pose in sim.link_poses().items()}
    parents = [prefix + j.parent for j in sim.skeleton.joints]
    children = [prefix + j.child for j in sim.skeleton.joints]
    base = prefix + sim.skeleton.base
    return transforms_message(relative_frames(parents, children, poses), world, base, *poses[base])


def scene_markers(sim: Simulation, world: str = "world", namespace: str = "scene") -> Markers:
    """Every primitive shape of the scene's bodies (not the hand) as a marker in the world frame.

    Meshes and planes are left out; a capsule is drawn as a cylinder over its full length.  Ids
    are stable while the scene's bodies stay (one per visual shape, in body order).
    """
    kinds, scales, colours, frames, local = [], [], [], [], []
    c = sim.client
    for i in range(p.getNumBodies(physicsClientId=c)):
        body = p.getBodyUniqueId(i, physicsClientId=c)
        if body == sim.hand_id:
            continue
        for shape in p.getVisualShapeData(body, physicsClientId=c):
            link, geom, dims, rgba = shape[1], shape[2], shape[3], shape[7]
            if geom not in _SHAPES:
                continue
            if link < 0:
                pos, orn = p.getBasePositionAndOrientation(body, physicsClientId=c)
            else:
                pos, orn = p.getLinkState(body, link, computeForwardKinematics=True, physicsClientId=c)[:2]
            kind, scale = _SHAPES[geom]
            kinds.append(kind)
            scales.append(scale(dims))
            colours.append(rgba)
            frames.append((*pos, *orn))
            local.append((*shape[5], *shape[6]))
    n = len(kinds)
    frames_a, local_a = np.reshape(frames, (n, 7)), np.reshape(local, (n, 7))
    positions, rotations = np.zeros((0, 3)), np.zeros((0, 4))
    if n:
        frame = Rotation.from_quat(frames_a[:, 3:])
        positions = frames_a[:, :3] + frame.apply(local_a[:, :3])
        rotations = (frame * Rotation.from_quat(local_a[:, 3:])).as_quat()
    return Markers(
        kinds=kinds,
        frame_ids=[world] * n,
        namespaces=[namespace] * n,
        ids=np.arange(n),
        positions=positions,
        orientations=rotations,
        scales=np.reshape(scales, (n, 3)),
        colours=np.reshape(colours, (n, 4)),
        texts=[""] * n,
    )
