"""Node ``grasp.experience`` in the harness: scripted postures and contacts in, targets out."""

import numpy as np
import pytest

from handflow.framework.messages import Contacts, JointState, Label
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.grasp.experience import GraspDataset
from handflow.plugins.grasp.hand_layout import hand_layout
from handflow.plugins.grasp.node import ExperienceGraspNode
from handflow.plugins.hands.joints import HAND_MODELS

NAMES = HAND_MODELS["shadow"].names


def joints(q):
    return JointState(names=list(NAMES), positions=np.asarray(q, float), hand="shadow")


def contacts(*pairs):
    return Contacts(segments=[s for s, _ in pairs], bodies=[b for _, b in pairs], forces=np.ones(len(pairs)))


def test_node_closes_holds_and_ignores_table_contacts(tmp_path):
    h = NodeHarness(ExperienceGraspNode, {"pregrasp": {}, "rate_hz": 50}, base_dir=tmp_path).setup()
    h.tick()
    assert "targets" not in h.published  # nothing before the first posture
    q = np.zeros(len(NAMES))
    h.send("joints", joints(q))
    h.send("contacts", contacts(("FF_distal", "table")))  # the table is not the object
    h.tick(3)
    t = h.published["targets"][-1]
    assert t.names == list(NAMES) and t.positions[NAMES.index("FFJ3")] > 0
    h.send("contacts", contacts(("FF_distal", "cylinder")))
    h.tick()
    frozen = h.published["targets"][-1].positions[NAMES.index("FFJ3")]
    h.tick(3)
    assert h.published["targets"][-1].positions[NAMES.index("FFJ3")] == frozen
    assert h.published["targets"][-1].positions[NAMES.index("MFJ3")] > frozen
    status = h.published["status"][-1]
    assert status.state == "C" and status.text == "FF_distal"


def test_release_trigger_opens_and_grasp_restarts(tmp_path):
    h = NodeHarness(ExperienceGraspNode, {"autostart": False}, base_dir=tmp_path).setup()
    h.send("joints", joints(np.zeros(len(NAMES))))
    h.tick()
    assert h.published["status"][-1].state == "idle"
    h.send("trigger", Label(label="grasp"))
    h.tick()
    assert h.published["status"][-1].state in ("A", "B")
    h.send("trigger", Label(label="release"))
    h.tick()
    assert h.published["status"][-1].state == "idle"
    np.testing.assert_allclose(h.published["targets"][-1].positions, h.node.controller.pregrasp)


def test_node_loads_an_experience_file_relative_to_the_graph(tmp_path):
    names = hand_layout("shadow").finger_joints
    GraspDataset(names, np.full((2, len(names)), 0.4), ["box", "box"], np.zeros((2, 4)), [[], []], np.zeros(2)).save(
        tmp_path / "grasps.npz"
    )
    h = NodeHarness(
        ExperienceGraspNode, {"experience": "grasps.npz", "steer_before_contact": True}, base_dir=tmp_path
    ).setup()
    assert h.node.controller.experience.kind == "database"
    q = h.node.controller.pregrasp
    ff = []
    for _ in range(30):  # the simulator follows the targets exactly
        h.send("joints", joints(q))
        h.tick()
        q = h.published["targets"][-1].positions
        ff.append(q[NAMES.index("FFJ3")])
    assert h.node.controller.match_index is not None
    np.testing.assert_allclose(ff[:20], np.arange(1, 21) / 60)  # phase B: heading for the match (FFJ3 = 0.4)
    assert ff[-1] > 0.4


def test_wrong_joint_state_is_refused_with_advice(tmp_path):
    h = NodeHarness(ExperienceGraspNode, {}, base_dir=tmp_path).setup()
    h.send("joints", JointState(names=["FFJ3"], positions=np.zeros(1)))  # dropped, as by the runtime
    assert "lacks joints" in h.dropped[0][1]
    with pytest.raises(Exception, match="extra"):
        NodeHarness(ExperienceGraspNode, {"speed": 3})
