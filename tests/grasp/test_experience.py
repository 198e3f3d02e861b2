"""Experience bases, grasp datasets, hand layout / PCP masks, wrench quality (docs/grasping.md)."""

import numpy as np
import pytest

from handflow.plugins.grasp.controller import SHADOW_PREGRASP
from handflow.plugins.grasp.episode import GraspPose
from handflow.plugins.grasp.experience import ExperienceBase, GraspDataset
from handflow.plugins.grasp.generation import FIXED_PREGRASP_RANGES, PREGRASP_RANGES, _jitter, random_pregrasp
from handflow.plugins.grasp.grid import HARD_GRID
from handflow.plugins.grasp.hand_layout import hand_layout
from handflow.plugins.grasp.pcp import best_match_index, pcp_distances
from handflow.plugins.grasp.som import SOM, save_som
from handflow.plugins.grasp.stability import grasp_wrench_quality

NAMES = hand_layout("shadow").finger_joints


def dataset(n=12, seed=0):
    rng = np.random.default_rng(seed)
    objs = np.array(["box", "sphere"])[rng.integers(0, 2, n)]
    return GraspDataset(
        NAMES,
        rng.uniform(0, 1, (n, len(NAMES))),
        objs,
        rng.uniform(0, 0.05, (n, 4)),
        [["FF_distal", "TH_distal"]] * n,
        rng.uniform(0, 1, n),
        {"seed": seed},
    )


def test_pcp_distance_counts_only_selected_joints():
    P = np.array([[0.0, 9.0], [1.0, 0.0]])
    np.testing.assert_allclose(pcp_distances(P, [0.0, 0.0], [1, 0]), [0.0, 1.0])
    assert best_match_index(P, [0.0, 0.0]) == 1
    assert best_match_index(P, [0.0, 0.0], [True, False]) == 0
    with pytest.raises(ValueError, match="0 or 1"):
        pcp_distances(P, [0, 0], [0.5, 1])


def test_pcp_mask_specifies_joints_between_palm_and_touching_segment():
    layout = hand_layout("shadow")
    s = dict(zip(layout.names, layout.pcp_mask(["FF_middle", "palm"])))
    assert [n for n, on in s.items() if on] == ["FFJ4", "FFJ3", "FFJ2"]
    s = dict(zip(layout.names, layout.pcp_mask(["TH_metacarpal", "LF_proximal"])))
    assert [n for n, on in s.items() if on] == ["LFJ5", "LFJ4", "LFJ3", "THJ5", "THJ4"]
    assert {f.name: f.tip for f in layout.fingers} == {
        "TH": "TH_distal",
        "FF": "FF_distal",
        "MF": "MF_distal",
        "RF": "RF_distal",
        "LF": "LF_distal",
    }


def test_dataset_round_trip_and_selection(tmp_path):
    data = dataset()
    data.save(tmp_path / "grasps.npz")
    back = GraspDataset.load(tmp_path / "grasps.npz")
    np.testing.assert_array_equal(back.postures, data.postures)
    assert back.contacts == data.contacts and back.metadata == {"seed": 0} and back.names == data.names
    boxes = back.select("box")
    assert set(boxes.objects) == {"box"} and len(boxes) == int(np.sum(data.objects == "box"))


def test_experience_base_loads_a_som_or_a_dataset(tmp_path):
    data = dataset(30)
    data.save(tmp_path / "grasps.npz")
    som = SOM(rows=3, cols=3, epochs=3, random_state=0).fit(data.postures)
    save_som(som, tmp_path / "som.npz", {"names": list(NAMES)})
    db = ExperienceBase.load(tmp_path / "grasps.npz")
    sm = ExperienceBase.load(tmp_path / "som.npz")
    assert (db.kind, len(db)) == ("database", 30) and (sm.kind, len(sm)) == ("som", 9)
    k, posture = db.best_match(data.postures[7])
    assert k == 7
    manifold = ExperienceBase(np.vstack([data.postures[:2]]), NAMES)  # e.g. manipulation-manifold postures
    assert manifold.best_match(data.postures[1])[0] == 1
    with pytest.raises(FileNotFoundError, match="grasp-experience"):
        ExperienceBase.load(tmp_path / "missing.npz")


def test_wrench_quality_tells_force_closure_apart():
    centre = np.zeros(3)
    # four contacts around a sphere of radius 3 cm, forces pointing to the centre: force closure
    pts = 0.03 * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0.3], [0, -1, -0.3]], dtype=float)
    assert grasp_wrench_quality(pts, -pts, centre, 0.03) > 0.05
    # all pushes from one side: the object can escape
    one_side = pts[[0, 2]]
    assert grasp_wrench_quality(one_side, -one_side, centre, 0.03) <= 0
    assert grasp_wrench_quality(pts[:1], -pts[:1], centre, 0.03) == 0.0


def test_fixed_pregrasp_ranges_always_give_the_controller_pregrasp():
    rng = np.random.default_rng(0)
    assert random_pregrasp(rng, FIXED_PREGRASP_RANGES) == SHADOW_PREGRASP
    ranges = HARD_GRID.pose_ranges("box")
    assert _jitter(rng, GraspPose(0.03), dict(SHADOW_PREGRASP), FIXED_PREGRASP_RANGES, ranges)[1] == SHADOW_PREGRASP
    varied = random_pregrasp(rng, PREGRASP_RANGES)
    assert set(varied) == set(PREGRASP_RANGES) and varied["THJ5"] != SHADOW_PREGRASP["THJ5"]
