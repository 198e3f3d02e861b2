"""Grasp experience generation in pybullet (docs/grasping.md).

Documented method (the thesis pulled fingertips to the object with virtual springs from a few
manually chosen start postures; any method that yields stable grasps is allowed): *randomised
tactile grasping with a stability filter*.  Every trial draws

- an object pose uniformly from the pose ranges covering the evaluation grid
  (:meth:`~.grid.GraspGrid.pose_ranges`), rejecting poses near a grid pose
  (:meth:`~.grid.GraspGrid.near_grid`): the experience is built from poses disjoint from the
  evaluation grid, under the grid's friction and disturbance test,
- a random pre-grasp (thumb rotation/abduction/flexion, finger spread and flexion within
  :data:`PREGRASP_RANGES`) and a random proximal/distal speed ratio λ from :data:`LAMBDA_RANGE`,

runs the purely tactile controller (phases A, C, D without experience) and keeps the final posture
of every grasp that passes the :class:`~.stability.DisturbanceTest`, with the object type, pose,
touching segments and wrench quality.  Many different start postures give the variety of grasp
postures the thesis obtained from its start postures.  Local exploration (like the thesis' springs
around each start posture): after a stable grasp, ``local_trials`` more trials reuse its λ with the
pose and pre-grasp jittered by :data:`LOCAL_JITTER` — successes cluster, so this raises the yield.
"""

from __future__ import annotations

import sys
from collections.abc import Callable

import numpy as np

from handflow.plugins.hands.joints import HAND_MODELS

from .controller import SHADOW_PREGRASP, ControllerConfig, ExperienceGraspController
from .episode import EpisodeConfig, GraspPose, run_grasp
from .experience import GraspDataset
from .grid import HARD_GRID, GraspGrid
from .hand_layout import hand_layout

PREGRASP_RANGES = {
    "THJ5": (-0.6, 0.6),
    "THJ4": (0.0, 1.22),
    "THJ2": (-0.2, 0.4),
    "THJ1": (0.0, 0.5),
    **{f"{f}J4": (-0.15, 0.15) for f in ("FF", "MF", "RF", "LF")},
    **{f"{f}J3": (0.0, 0.5) for f in ("FF", "MF", "RF", "LF")},
    **{f"{f}J2": (0.0, 0.4) for f in ("FF", "MF", "RF", "LF")},
}
"""Uniform ranges (rad) of the random pre-grasp of the ShadowHand-like hand; other joints 0."""

FIXED_PREGRASP_RANGES = {n: (v, v) for n, v in SHADOW_PREGRASP.items()}
"""Pre-grasp ranges that always give the evaluation's fixed pre-grasp (only pose and λ vary)."""

LAMBDA_RANGE = (0.7, 2.0)
"""Uniform range of the proximal/distal closing-speed ratio λ of the generating controller."""

MAX_DRAWS = 1000
"""Random poses drawn at most to find one away from the grid (:meth:`~.grid.GraspGrid.near_grid`)."""

LOCAL_JITTER = {"x": 0.006, "y": 0.006, "gap": 0.004, "yaw_deg": 8.0, "pregrasp": 0.08}
"""Standard deviations of the local exploration around a stable grasp (m, m, m, deg, rad)."""
MAX_LOCAL_DEPTH = 2
"""Neighbours of neighbours are explored, no further (keeps the search from staying in one cluster)."""


def random_pose(rng: np.random.Generator, grid: GraspGrid, obj: str) -> GraspPose:
    """A uniform pose in the grid's ranges of ``obj`` that is not near a grid pose."""
    ranges = grid.pose_ranges(obj)
    for _ in range(MAX_DRAWS):
        pose = GraspPose(**{k: float(rng.uniform(*ranges[k])) for k in ranges})
        if not grid.near_grid(obj, pose):
            return pose
    raise ValueError(f"grid '{grid.name}' leaves no room for experience poses of '{obj}'")


def random_pregrasp(rng: np.random.Generator, ranges: dict = PREGRASP_RANGES) -> dict[str, float]:
    return {name: float(rng.uniform(lo, hi)) for name, (lo, hi) in ranges.items()}


def _jitter(
    rng: np.random.Generator, pose: GraspPose, pregrasp: dict, ranges: dict, pose_ranges: dict
) -> tuple[GraspPose, dict]:
    near = GraspPose(
        **{k: float(np.clip(getattr(pose, k) + rng.normal(0.0, LOCAL_JITTER[k]), *pose_ranges[k])) for k in pose_ranges}
    )
    sd = LOCAL_JITTER["pregrasp"]
    pre = {n: float(np.clip(v + rng.normal(0.0, sd), *ranges[n])) for n, v in pregrasp.items()}
    return near, pre


def generate_experience(
    objects,
    n_trials: int | dict[str, int],
    seed: int = 0,
    hand: str = "shadow",
    local_trials: int = 3,
    base: ControllerConfig = ControllerConfig(),
    episode: EpisodeConfig = EpisodeConfig(),
    progress: Callable[[str], None] | None = None,
    pregrasp_ranges: dict = PREGRASP_RANGES,
    grid: GraspGrid = HARD_GRID,
) -> GraspDataset:
    """Run ``n_trials`` randomised grasps per object and return the stable ones as a dataset.

    ``n_trials`` may be a dict ``{object: trials}`` to balance the experience: objects with a low yield
    of stable grasps (the lying cylinder) need more trials for a comparable number of grasps.
    ``pregrasp_ranges`` (default :data:`PREGRASP_RANGES`) bounds the random pre-grasp; ranges with equal
    ends fix a joint (:data:`FIXED_PREGRASP_RANGES`: always the controller's pre-grasp).  Poses
    cover ``grid`` but stay away from its poses; the episodes use the grid's conditions.
    """
    trials = n_trials if isinstance(n_trials, dict) else dict.fromkeys(objects, n_trials)
    bad = {obj: trials.get(obj) for obj in objects if not isinstance(trials.get(obj), int) or trials[obj] < 1}
    if bad:
        raise ValueError(f"every object needs ≥ 1 trials, got {bad}")
    outside = [obj for obj in objects if obj not in grid.objects]
    if outside:
        raise ValueError(f"grid '{grid.name}' has no poses for {outside}; its objects: {', '.join(grid.objects)}")
    layout = hand_layout(hand)
    model = HAND_MODELS[hand]
    names = layout.finger_joints
    cols = [layout.names.index(n) for n in names]
    rng = np.random.default_rng(seed)
    episode = grid.episode(episode)
    postures, objs, poses, contacts, quality = [], [], [], [], []
    counts = {}
    for obj in objects:
        kept = valid = 0
        queue: list[tuple[GraspPose, dict, float, int]] = []
        for t in range(trials[obj]):
            while queue and grid.near_grid(obj, queue[0][0]):
                queue.pop(0)
            if queue:
                pose, pregrasp, lam, depth = queue.pop(0)
            else:
                pose, pregrasp, lam, depth = (
                    random_pose(rng, grid, obj),
                    random_pregrasp(rng, pregrasp_ranges),
                    float(rng.uniform(*LAMBDA_RANGE)),
                    0,
                )
            config = base.model_copy(update={"pregrasp": pregrasp, "lam": lam})
            controller = ExperienceGraspController(layout, model.lower, model.upper, None, config)
            result = run_grasp(obj, pose, controller, episode, seed=int(rng.integers(2**31)), hand=hand)
            valid += result.valid
            if result.valid and result.stable:
                kept += 1
                if depth < MAX_LOCAL_DEPTH:
                    queue.extend(
                        (*_jitter(rng, pose, pregrasp, pregrasp_ranges, grid.pose_ranges(obj)), lam, depth + 1)
                        for _ in range(local_trials)
                    )
                postures.append(result.posture[cols])
                objs.append(obj)
                poses.append(result.pose)
                contacts.append(result.touched)
                quality.append(result.quality)
            if progress is not None and (t + 1) % 20 == 0:
                progress(f"{obj}: {t + 1}/{trials[obj]} trials, {kept} stable grasps kept")
        counts[obj] = {"trials": trials[obj], "valid": valid, "stable": kept}
    meta = {
        "hand": hand,
        "method": "randomised tactile grasping + disturbance test",
        "seed": seed,
        "counts": counts,
        "pregrasp_ranges": {k: list(v) for k, v in pregrasp_ranges.items()},
        "grid": grid.name,
        "lateral_friction": grid.lateral_friction,
        "pose_ranges": {obj: {k: list(v) for k, v in grid.pose_ranges(obj).items()} for obj in objects},
    }
    return GraspDataset(
        names, np.array(postures).reshape(-1, len(names)), objs, np.array(poses).reshape(-1, 4), contacts, quality, meta
    )


def stderr_progress(text: str) -> None:
    print(text, file=sys.stderr, flush=True)
