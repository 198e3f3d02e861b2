"""Grasp stability in pybullet: the disturbance test and a wrench-space quality (docs/grasping.md).

**Disturbance test** (the documented stability proxy; the thesis used force closure in zero gravity):
after the grasp, the table is removed so that only the hand holds the object against gravity; after
``hold_s`` the object receives ``n_pushes`` random disturbances, each a force of ``force_n`` and a
torque of ``torque_nm`` in uniformly random directions held for ``push_s``, with ``rest_s`` between
them.  The grasp is *stable* when, at the end, the object moved less than ``max_shift_m`` and turned
less than ``max_turn_deg`` from its pose at the end of the grasp, and still touches at least
``min_contacts`` hand segments.  Disturbance directions come from a seeded generator.

**Wrench-space quality** (thesis 4.3: force closure ⇔ the worst-case disturbance wrench of the L1
grasp wrench space is positive, Haschke et al. 2005): each contact point contributes the wrenches of
the ``n_edges`` edges of its linearised friction cone (coefficient ``mu``) with unit normal force;
torques are divided by the object's radius; the quality is the signed distance from the origin to
the boundary of their convex hull (> 0: force closure).  Computed at the end of the grasp, before
the disturbance test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ..simulator.bullet import pybullet as p


@dataclass(frozen=True)
class DisturbanceTest:
    """Parameters of the disturbance test (SI units)."""

    hold_s: float = 0.5
    n_pushes: int = 4
    push_s: float = 0.1
    rest_s: float = 0.15
    force_n: float = 0.5
    torque_nm: float = 0.01
    max_shift_m: float = 0.03
    max_turn_deg: float = 45.0
    min_contacts: int = 2

    @property
    def duration_s(self) -> float:
        return self.hold_s + self.n_pushes * (self.push_s + self.rest_s)


def random_directions(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` unit vectors uniformly distributed on the sphere."""
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def rotation_angle_deg(q0, q1) -> float:
    """Angle (deg) of the rotation between two pybullet quaternions (x, y, z, w)."""
    dot = abs(float(np.dot(np.asarray(q0, float), np.asarray(q1, float))))
    return float(np.degrees(2.0 * np.arccos(min(1.0, dot))))


def grasp_wrench_quality(points, normals, centre, radius: float, mu: float = 0.8, n_edges: int = 8) -> float:
    """Signed distance of the origin to the boundary of the L1 grasp wrench space (> 0: force closure).

    ``points`` (n, 3) contact points on the object, ``normals`` (n, 3) the force directions the hand
    applies (into the object), ``centre`` the object's centre of mass, ``radius`` the torque scale.
    Fewer than two contacts, or a degenerate wrench set, give quality 0 or below.
    """
    P = np.atleast_2d(np.asarray(points, dtype=float))
    N = np.atleast_2d(np.asarray(normals, dtype=float))
    if len(P) < 2:
        return 0.0
    N = N / np.linalg.norm(N, axis=1, keepdims=True)
    helper = np.where(np.abs(N[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(N, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(N, t1)
    ang = 2 * np.pi * np.arange(n_edges) / n_edges
    forces = N[:, None, :] + mu * (
        np.cos(ang)[None, :, None] * t1[:, None, :] + np.sin(ang)[None, :, None] * t2[:, None, :]
    )
    forces /= np.linalg.norm(forces, axis=2, keepdims=True)
    arms = (P - np.asarray(centre, dtype=float))[:, None, :]
    torques = np.cross(np.broadcast_to(arms, forces.shape), forces) / radius
    W = np.concatenate([forces, torques], axis=2).reshape(-1, 6)
    try:
        hull = ConvexHull(W, qhull_options="QJ")
    except (QhullError, ValueError):
        return 0.0
    offsets = -hull.equations[:, -1]  # facet: n·x + b ≤ 0 inside, so distance of origin = −b
    return float(np.min(offsets))


def object_contacts(client: int, hand_id: int, object_id: int) -> tuple[np.ndarray, np.ndarray]:
    """Contact points on the object and the hand's force directions (into the object)."""
    pts, nrm = [], []
    for c in p.getContactPoints(bodyA=object_id, bodyB=hand_id, physicsClientId=client):
        pts.append(c[5])  # position on A (the object)
        nrm.append(c[7])  # normal on B pointing towards A: the hand pushes along it
    return np.array(pts).reshape(-1, 3), np.array(nrm).reshape(-1, 3)
