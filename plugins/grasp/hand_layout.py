"""Fingers, segments and joints of a simulated hand as the grasp controller sees them (docs/grasping.md).

Derived from the simulator's kinematic skeleton (:func:`handflow.plugins.simulator.hand_geometry.build_skeleton`),
so the contact segment names of :meth:`Simulation.contacts` map directly to fingers:

- a *finger* is a joint chain that starts at the palm (thumb, index … little; the wrist is not a finger);
- a *segment* is a link with geometry (a capsule); the joint that moves it is its joint in the chain;
- the *tip* is the last segment of a chain;
- *closing joints* are the joints that move a segment (flexion: MCP/PIP/DIP, thumb THJ4/THJ2/THJ1);
  the others (spread, thumb rotation THJ5, thumb hub THJ3, palm arch LFJ5) are placed by the
  pre-grasp / experience only — documented choice;
- the *proximal* joint of a finger (speed λ·γ in the closing heuristic, thesis eq. 4.6) is its first
  closing joint, the others are *distal*.

PCP (thesis eq. 4.2): a contact on segment ``S_i,k`` specifies the joints ``j ≤ k`` of finger ``i``
(every joint between the palm and the touching segment).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from handflow.plugins.simulator.hand_geometry import build_skeleton


@dataclass(frozen=True)
class Finger:
    """One kinematic chain from the palm: joints in order, which joint moves which segment."""

    name: str
    joints: tuple[str, ...]
    segments: dict[str, int]  # segment link name → position of its joint in ``joints``

    @property
    def tip(self) -> str:
        return max(self.segments, key=self.segments.get)

    @property
    def closing(self) -> tuple[int, ...]:
        """Chain positions of the closing joints (those that move a segment)."""
        return tuple(sorted(self.segments.values()))


@dataclass(frozen=True)
class HandLayout:
    """All fingers of one hand plus the hand's joint order (the order of every posture vector)."""

    hand: str
    names: tuple[str, ...]
    fingers: tuple[Finger, ...]

    @property
    def finger_joints(self) -> list[str]:
        """Joints that belong to a finger (the dimensions of grasp postures), in hand order."""
        inside = {j for f in self.fingers for j in f.joints}
        return [n for n in self.names if n in inside]

    def finger_of(self, segment: str) -> Finger | None:
        for f in self.fingers:
            if segment in f.segments:
                return f
        return None

    def pcp_mask(self, touched, names=None) -> np.ndarray:
        """The PCP selection ``s`` over ``names`` (default: the hand's joints) for touched segments.

        Segments that belong to no finger (palm, forearm) specify nothing.
        """
        names = list(self.names if names is None else names)
        where = {n: k for k, n in enumerate(names)}
        s = np.zeros(len(names), dtype=bool)
        for seg in touched:
            f = self.finger_of(seg)
            if f is None:
                continue
            for j in f.joints[: f.segments[seg] + 1]:
                if j in where:
                    s[where[j]] = True
        return s


@cache
def hand_layout(hand: str = "shadow") -> HandLayout:
    """The :class:`HandLayout` of simulator hand ``hand`` (``shadow`` | ``gifu`` | ``human``)."""
    sk = build_skeleton(hand)
    children: dict[str, list] = {}
    for j in sk.joints:
        children.setdefault(j.parent, []).append(j)
    fingers = []
    for root in children.get(sk.palm_link, []):
        joints, segments, j = [], {}, root
        while True:
            joints.append(j.name)
            if j.length > 0:
                segments[j.child] = len(joints) - 1
            nxt = children.get(j.child, [])
            if len(nxt) != 1:
                break
            j = nxt[0]
        name = root.child.split("_")[0]
        fingers.append(Finger(name=name, joints=tuple(joints), segments=segments))
    return HandLayout(hand=hand, names=tuple(sk.model.names), fingers=tuple(fingers))
