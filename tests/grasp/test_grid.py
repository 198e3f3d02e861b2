"""Evaluation grids: jittered seeded trials, experience disjoint from the grid, headroom (docs/grasping.md)."""

import numpy as np
import pytest

from handflow.plugins.grasp import cli
from handflow.plugins.grasp.experience import POSE_FIELDS, GraspDataset
from handflow.plugins.grasp.generation import random_pose
from handflow.plugins.grasp.grid import EXCLUSION, HARD_GRID, POSE_JITTER, QUICK_HARD_GRID, THESIS_GRID, GraspGrid
from handflow.plugins.grasp.plots import success_table

JITTER = np.array([POSE_JITTER[k] for k in POSE_FIELDS])


def test_hard_grid_is_harder_than_the_thesis_grid():
    assert HARD_GRID.lateral_friction < THESIS_GRID.lateral_friction
    assert {"small_sphere", "thin_cylinder"} <= set(HARD_GRID.objects)
    assert max(np.abs(HARD_GRID.poses["sphere"]["y"])) > max(np.abs(THESIS_GRID.poses["sphere"]["y"]))
    assert min(HARD_GRID.poses["box"]["yaw_deg"]) < min(THESIS_GRID.poses["box"]["yaw_deg"])
    for obj in QUICK_HARD_GRID.objects:  # the quick grid is a subset of the full one
        assert {p.as_array().tobytes() for p in QUICK_HARD_GRID.nominal(obj)} <= {
            p.as_array().tobytes() for p in HARD_GRID.nominal(obj)
        }


def test_seeds_jitter_the_grid_reproducibly_within_the_bound():
    nominal = np.array([p.as_array() for p in HARD_GRID.nominal("box")])
    a, b, a2 = (np.array([p.as_array() for p in HARD_GRID.trials("box", s)]) for s in (0, 1, 0))
    assert np.array_equal(a, a2) and not np.allclose(a, b)
    assert np.all(np.abs(a - nominal) <= JITTER) and np.all(np.abs(b - nominal) <= JITTER)
    assert THESIS_GRID.trials("box", 3) == THESIS_GRID.nominal("box")  # no jitter


def test_near_grid_and_random_experience_poses_stay_disjoint():
    pose = HARD_GRID.nominal("small_sphere")[4]
    assert HARD_GRID.near_grid("small_sphere", pose)
    moved = pose.as_array() + 1.01 * np.array([EXCLUSION["x"], 0.0, 0.0, 0.0])
    assert not HARD_GRID.near_grid("small_sphere", type(pose)(*moved))
    rng = np.random.default_rng(0)
    for obj in HARD_GRID.objects:
        ranges = HARD_GRID.pose_ranges(obj)
        for _ in range(200):
            p = random_pose(rng, HARD_GRID, obj)
            assert not HARD_GRID.near_grid(obj, p)
            assert all(lo <= v <= hi for v, (lo, hi) in zip(p.as_array(), ranges.values()))
    crowded = GraspGrid("crowded", {"sphere": {"x": (0.0,), "y": (0.0,), "gap": (0.0,), "yaw_deg": (0.0,)}})
    with pytest.raises(ValueError, match="no room"):  # ranges = exclusion box: every draw is near the grid
        random_pose(rng, crowded, "sphere")


def test_shipped_experience_is_built_away_from_every_evaluated_trial():
    data = GraspDataset.load(cli.DEFAULT_EXPERIENCE["hard"] / "grasps.npz")
    assert data.metadata["grid"] == "hard" and data.metadata["lateral_friction"] == HARD_GRID.lateral_friction
    for obj in HARD_GRID.objects:
        poses = data.poses[np.asarray(data.objects) == obj]
        assert len(poses) > 20
        nominal = np.array([p.as_array() for p in HARD_GRID.nominal(obj)])
        # every experience pose differs from every grid pose by more than twice the jitter in some field,
        # hence from every jittered trial by more than the jitter
        gaps = np.abs(poses[:, None, :] - nominal[None, :, :]) / np.array([EXCLUSION[k] for k in POSE_FIELDS])
        assert np.all(gaps.max(axis=2) >= 1.0)


def test_success_table_places_outcomes_on_the_pose_grid():
    grid = GraspGrid("g", {"sphere": {"x": (0.02, 0.05), "y": (0.0,), "gap": (0.005, 0.02), "yaw_deg": (0.0,)}})
    poses = [p.as_array().tolist() for p in grid.nominal("sphere")]  # (x, gap) order: (2,.5) (2,2) (5,.5) (5,2)
    outcomes = [
        {"object": "sphere", "seed": s, "pose": poses[k], "experience": (k != 1, True) if k < 3 else None}
        for s in (0, 1)
        for k in range(4)
    ]
    table, rows, cols = success_table(outcomes, grid, "sphere", "experience")
    assert rows == [(0.005, 0.0), (0.02, 0.0)] and cols == [(0.02, 0.0), (0.05, 0.0)]
    assert table[0].tolist() == [1.0, 1.0] and table[1, 0] == 0.0 and np.isnan(table[1, 1])
