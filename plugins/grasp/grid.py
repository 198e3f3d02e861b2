"""Evaluation grids of grasp poses and the conditions they are grasped under (docs/grasping.md).

A :class:`GraspGrid` names, per object, the values of each pose field (:class:`~.episode.GraspPose`:
offset along the fingers ``x`` and across the palm ``y``, ``gap`` below the palm, ``yaw_deg``), the
object friction and the :class:`~.stability.DisturbanceTest` of its episodes.  Every pose of the
product of the values is grasped.

Seeds (documented choice :data:`POSE_JITTER`): evaluation seed ``s`` moves every grid pose by a
seeded uniform jitter of at most :data:`POSE_JITTER` per field and draws the disturbance directions
of the stability test from its own seeded generator — each seed grasps physically different trials
around the same nominal grid.  Experience must be built from poses *disjoint* from the grid:
:meth:`GraspGrid.near_grid` is true within :data:`EXCLUSION` (twice the jitter) of a grid pose in
every field, and :func:`~.generation.generate_experience` rejects such poses, so no experience pose
lies within the jitter of any evaluated pose.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from .episode import EpisodeConfig, GraspPose
from .experience import POSE_FIELDS
from .stability import DisturbanceTest

POSE_JITTER = {"x": 0.002, "y": 0.002, "gap": 0.001, "yaw_deg": 3.0}
"""Half-width of the seeded uniform pose jitter of an evaluation seed (m, m, m, deg)."""
EXCLUSION = {k: 2.0 * v for k, v in POSE_JITTER.items()}
"""Experience poses closer than this to a grid pose in every field are rejected (twice the jitter)."""


@dataclass(frozen=True)
class GraspGrid:
    """Pose values per object (field → values) and the grasp conditions of one evaluation grid."""

    name: str
    poses: dict[str, dict[str, tuple[float, ...]]]
    lateral_friction: float = 0.8
    test: DisturbanceTest = field(default_factory=DisturbanceTest)
    jitter: bool = True
    experience_of: str = ""
    """Name of the grid whose experience this one uses (a subset uses its full grid's); default its own."""

    def __post_init__(self) -> None:
        for obj, values in self.poses.items():
            if set(values) != set(POSE_FIELDS) or not all(values.values()):
                raise ValueError(f"grid '{self.name}', object '{obj}': give values for each of {POSE_FIELDS}")

    @property
    def experience_grid(self) -> str:
        return self.experience_of or self.name

    @property
    def objects(self) -> tuple[str, ...]:
        return tuple(self.poses)

    def nominal(self, obj: str) -> list[GraspPose]:
        """The grid poses of ``obj`` (product of its field values)."""
        v = self.poses[obj]
        return [GraspPose(*vals) for vals in itertools.product(*(v[k] for k in POSE_FIELDS))]

    def trials(self, obj: str, seed: int) -> list[GraspPose]:
        """The poses grasped under evaluation ``seed``: the grid, jittered by :data:`POSE_JITTER`."""
        poses = self.nominal(obj)
        if not self.jitter:
            return poses
        rng = np.random.default_rng([seed, len(self.name), *map(ord, obj)])
        half = np.array([POSE_JITTER[k] for k in POSE_FIELDS])
        moved = np.array([q.as_array() for q in poses]) + rng.uniform(-1.0, 1.0, (len(poses), 4)) * half
        return [GraspPose(*map(float, row)) for row in moved]

    def episode(self, base: EpisodeConfig = EpisodeConfig()) -> EpisodeConfig:
        """``base`` with this grid's friction and disturbance test."""
        return EpisodeConfig(**{**base.__dict__, "lateral_friction": self.lateral_friction, "test": self.test})

    def near_grid(self, obj: str, pose: GraspPose) -> bool:
        """Whether ``pose`` lies within :data:`EXCLUSION` of a grid pose of ``obj`` in every field."""
        grid = np.array([q.as_array() for q in self.nominal(obj)])
        tol = np.array([EXCLUSION[k] for k in POSE_FIELDS])
        return bool(np.any(np.all(np.abs(grid - pose.as_array()) < tol, axis=1)))

    def pose_ranges(self, obj: str) -> dict[str, tuple[float, float]]:
        """Continuous ranges covering the grid of ``obj`` plus :data:`EXCLUSION` (experience generation)."""
        v = self.poses[obj]
        return {k: (min(v[k]) - EXCLUSION[k], max(v[k]) + EXCLUSION[k]) for k in POSE_FIELDS}


_FLAT = {"x": (0.02, 0.035, 0.05), "gap": (0.005, 0.02)}
HARD_GRID = GraspGrid(
    "hard",
    {
        "box": {**_FLAT, "y": (-0.012, 0.012), "yaw_deg": (-60.0, -40.0, 20.0, 35.0)},
        "thin_cylinder": {**_FLAT, "y": (-0.012, 0.012), "yaw_deg": (-45.0, -15.0, 15.0, 30.0)},
        "small_sphere": {**_FLAT, "y": (-0.024, -0.012, 0.0, 0.012, 0.024), "yaw_deg": (0.0,)},
        "sphere": {**_FLAT, "y": (-0.024, 0.024), "yaw_deg": (0.0,)},
    },
    lateral_friction=0.5,
)
"""The evaluation grid with headroom (docs/grasping.md): the box turned far (−60° … +35°), a thin
lying cylinder (r 1.5 cm), a small sphere (r 2 cm) across the palm and the thesis sphere off-centre
(±2.4 cm), all at friction 0.5 (scene default 0.8) — conditions where a pure closing motion often fails."""

QUICK_HARD_GRID = GraspGrid(
    "hard-quick",
    {
        "box": {"x": (0.035,), "y": (-0.012,), "gap": (0.005, 0.02), "yaw_deg": (-60.0, 20.0)},
        "thin_cylinder": {"x": (0.035,), "y": (0.012,), "gap": (0.005, 0.02), "yaw_deg": (-45.0, 15.0)},
        "small_sphere": {"x": (0.02, 0.05), "y": (-0.024, 0.024), "gap": (0.005,), "yaw_deg": (0.0,)},
        "sphere": {"x": (0.035,), "y": (-0.024, 0.024), "gap": (0.005,), "yaw_deg": (0.0,)},
    },
    lateral_friction=0.5,
    experience_of="hard",
)
"""A 14-pose subset of :data:`HARD_GRID` for ``--quick`` (seconds; it checks that everything runs)."""

_THESIS_XYG = {"x": (0.02, 0.03, 0.04, 0.05), "y": (-0.012, 0.0, 0.012), "gap": (0.005, 0.015, 0.025)}
THESIS_GRID = GraspGrid(
    "thesis",
    {
        "box": {**_THESIS_XYG, "yaw_deg": (-30.0, 0.0, 30.0)},
        "cylinder": {**_THESIS_XYG, "yaw_deg": (-30.0, 0.0, 30.0)},
        "sphere": {**_THESIS_XYG, "yaw_deg": (0.0,)},
    },
    jitter=False,
)
"""The grid of grasping passes 1–5 (thesis objects, friction 0.8, no jitter): the closing heuristic
alone holds 91.7 % of it (docs/benchmarks.md), too little headroom to show what experience adds."""

GRIDS = {g.name: g for g in (HARD_GRID, QUICK_HARD_GRID, THESIS_GRID)}
