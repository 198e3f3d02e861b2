"""Generated URDFs: they load, carry the mapping table's names/limits, and realise the spec's thumb geometry."""

import numpy as np
import pybullet as p
import pytest

from handflow.plugins.hands.joints import HAND_MODELS
from handflow.plugins.simulator.simulation import Simulation
from handflow.plugins.simulator.urdf import write_urdf


@pytest.mark.parametrize("hand", sorted(HAND_MODELS))
def test_urdf_loads_with_table_names_and_limits(hand, tmp_path):
    client = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(write_urdf(hand, tmp_path)), useFixedBase=True, physicsClientId=client)
        info = [
            p.getJointInfo(body, i, physicsClientId=client) for i in range(p.getNumJoints(body, physicsClientId=client))
        ]
        joints = {i[1].decode(): (i[8], i[9]) for i in info if i[2] == p.JOINT_REVOLUTE}
        model = HAND_MODELS[hand]
        assert sorted(joints) == sorted(model.names)
        for j in model.joints:
            assert joints[j.name] == pytest.approx((j.lower, j.upper), abs=1e-5)
    finally:
        p.disconnect(client)


def test_urdf_cache_reuses_the_generated_file(tmp_path):
    assert write_urdf("gifu", tmp_path) == write_urdf("gifu", tmp_path)
    assert len(list(tmp_path.iterdir())) == 1


def test_urdf_cache_is_keyed_on_content_so_changed_limits_regenerate(tmp_path, monkeypatch):
    """Changing a limit in the mapping table (e.g. th_abduction 20°…100°) must not reuse a stale URDF."""
    import dataclasses

    from handflow.plugins.simulator import hand_geometry

    human = HAND_MODELS["human"]
    before = write_urdf("human", tmp_path)
    joints = tuple(dataclasses.replace(j, upper=j.upper - 0.1) if j.name == "th_abduction" else j for j in human.joints)
    monkeypatch.setitem(hand_geometry.HAND_MODELS, "human", dataclasses.replace(human, joints=joints))
    after = write_urdf("human", tmp_path)
    assert (
        after != before and f'upper="{human.joints[human.index("th_abduction")].upper - 0.1:.6f}"' in after.read_text()
    )


def _axis_z(sim, link):
    ids = {v: k for k, v in sim.link_names.items()}
    orn = p.getLinkState(sim.hand_id, ids[link], computeForwardKinematics=True, physicsClientId=sim.client)[5]
    return np.array(p.getMatrixFromQuaternion(orn)).reshape(3, 3)[:, 2]


def _pose(sim, values):
    for name, q in values.items():
        p.resetJointState(sim.hand_id, int(sim.joint_ids[sim.index[name]]), q, physicsClientId=sim.client)


@pytest.mark.parametrize("theta0, theta1", [(0.3, 0.5), (-0.6, 0.9), (0.9, 0.2)])
def test_shadow_thumb_points_where_the_human_thumb_points(theta0, theta1):
    """docs/glove.md: α, β from the closed-form inverse give the same thumb axis as Θ0, Θ1."""
    s0, c0, s1, c1 = np.sin(theta0), np.cos(theta0), np.sin(theta1), np.cos(theta1)
    h = np.sqrt(0.5)
    alpha = np.arctan2(np.sqrt(0.5 + c1 * s0 * s1 + 0.5 * s1**2 * c0**2), h * (c1 - s1 * s0))
    beta = np.arctan2(c0 * s1, h * (c1 + s1 * s0))
    with Simulation("shadow") as shadow, Simulation("human") as human:
        _pose(shadow, {"THJ5": theta0, "THJ4": theta1})
        _pose(human, {"th_abduction": alpha, "th_roll": beta})
        np.testing.assert_allclose(_axis_z(shadow, "TH_metacarpal"), _axis_z(human, "th_metacarpal"), atol=1e-6)


def test_thumb_flexion_moves_the_opposed_thumb_towards_the_fingers():
    with Simulation("shadow") as sim:
        _pose(sim, {"THJ5": -0.75, "THJ4": 0.9, "MFJ3": 1.2, "MFJ2": 1.0, "MFJ1": 1.0})
        middle = sim.link_position("MF_distal")
        _pose(sim, {"THJ1": 0.0})
        far = np.linalg.norm(sim.link_position("TH_distal") - middle)
        _pose(sim, {"THJ2": 0.4})
        near = np.linalg.norm(sim.link_position("TH_distal") - middle)
        assert near < far
