"""The 3D view's data: viewer URDF and TF tree agree, forward kinematics equals pybullet, scene markers."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pybullet as p
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from handflow.framework.messages import JointState, Transforms
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.hands.joints import HAND_MODELS, HUMAN
from handflow.plugins.simulator.hand_geometry import build_skeleton
from handflow.plugins.simulator.kinematics import HandKinematics
from handflow.plugins.simulator.node import PybulletSimulatorNode
from handflow.plugins.simulator.robot_state import RobotStateNode
from handflow.plugins.simulator.simulation import Simulation
from handflow.plugins.simulator.urdf import urdf_text
from handflow.plugins.simulator.viewer import scene_markers, simulated_hand_transforms

HANDS = sorted(HAND_MODELS)


def _set_joints(sim: Simulation, q: np.ndarray) -> None:
    for jid, v in zip(sim.joint_ids, q):
        p.resetJointState(sim.hand_id, int(jid), float(v), physicsClientId=sim.client)


def assert_tree_matches_urdf(tf: Transforms, urdf: str, world: str = "world") -> None:
    """Every TF child is a URDF link, its parent is the joint's parent, and the world reaches every link."""
    robot = ET.fromstring(urdf)
    links = {link.get("name") for link in robot.iter("link")}
    joint_parent = {j.find("child").get("link"): j.find("parent").get("link") for j in robot.iter("joint")}
    assert set(tf.children) == links and len(tf.children) == len(links)  # each link once
    for parent, child in zip(tf.parents, tf.children):
        assert parent == joint_parent.get(child, world), child
    reached, frontier = {world}, [world]
    while frontier:
        frame = frontier.pop()
        for parent, child in zip(tf.parents, tf.children):
            if parent == frame and child not in reached:
                reached.add(child)
                frontier.append(child)
    assert links <= reached


@pytest.mark.parametrize("hand", HANDS)
def test_viewer_urdf_uses_only_standard_primitives(hand):
    robot = ET.fromstring(urdf_text(build_skeleton(hand), viewer=True, prefix="h/"))
    shapes = {g.tag for geom in robot.iter("geometry") for g in geom}
    assert shapes <= {"box", "cylinder", "sphere"} and "cylinder" in shapes
    assert not list(robot.iter("collision")) and not list(robot.iter("mesh"))
    assert all(link.get("name").startswith("h/") for link in robot.iter("link"))


@pytest.mark.parametrize("hand", HANDS)
def test_simulator_tf_tree_is_the_viewer_urdf_and_equals_forward_kinematics(hand):
    rng = np.random.default_rng(1)
    with Simulation(hand=hand) as sim:
        q = rng.uniform(sim.lower, sim.upper)
        _set_joints(sim, q)
        tf = simulated_hand_transforms(sim, "sim/")
        tf.check()
        assert_tree_matches_urdf(tf, urdf_text(sim.skeleton, viewer=True, prefix="sim/"))
        fk = HandKinematics(sim.skeleton, "sim/").transforms(sim.names, q)
        assert tf.children[1:] == fk.children
        np.testing.assert_allclose(tf.translations[1:], fk.translations, atol=1e-6)
        dots = np.abs((tf.rotations[1:] * fk.rotations).sum(axis=1))  # q and -q are one rotation
        np.testing.assert_allclose(dots, 1.0, atol=1e-9)
        # and the world poses: pybullet's fingertip frame = the chained forward kinematics (base pose applied)
        base_pos, base_quat = sim.link_poses()[sim.skeleton.base]
        poses = HandKinematics(sim.skeleton).link_poses(sim.names, q)
        for link, (pos, _) in poses.items():
            world = base_pos + Rotation.from_quat(base_quat).apply(pos)
            np.testing.assert_allclose(world, sim.link_position(link), atol=1e-6)


def test_human_forward_kinematics_turns_each_joint_by_its_angle_about_its_axis():
    skeleton = build_skeleton("human")
    kin = HandKinematics(skeleton)
    rng = np.random.default_rng(2)
    for q in (HUMAN.lower, HUMAN.upper, rng.uniform(HUMAN.lower, HUMAN.upper)):
        frames = kin.transforms(HUMAN.names, q)
        assert np.isfinite(frames.translations).all() and np.isfinite(frames.rotations).all()
        zero = kin.transforms(HUMAN.names, np.zeros(len(HUMAN)))
        qs = kin.joint_vector(HUMAN.names, q)
        for k, joint in enumerate(skeleton.joints):
            turn = Rotation.from_quat(zero.rotations[k]).inv() * Rotation.from_quat(frames.rotations[k])
            axis = np.asarray(joint.axis) / np.linalg.norm(joint.axis)
            np.testing.assert_allclose(turn.as_rotvec(), axis * qs[k], atol=1e-9)
    # flexing the index finger moves its tip palmar (-y in the palm frame, docs of hand_geometry)
    flexed = kin.link_poses(["ff_mcp", "ff_pip"], [1.2, 1.2])["ff_distal"][0]
    straight = kin.link_poses([], [])["ff_distal"][0]
    palm = Rotation.from_quat(kin.link_poses([], [])["palm"][1])
    assert palm.inv().apply(flexed - straight)[1] < -0.02


def test_scene_markers_are_the_simulated_balls():
    with Simulation(hand="gifu", scene="balls") as sim:
        sim.step(24)
        markers = scene_markers(sim)
        markers.check()
        state = sim.scene_state()
        spheres = markers.positions[[k == "sphere" for k in markers.kinds]]
        balls = np.array([[state[f"ball{i}_{c}"] for c in "xyz"] for i in (1, 2)])
        np.testing.assert_allclose(spheres, balls, atol=1e-9)
        assert {"cylinder", "cube"} <= set(markers.kinds) and len(set(markers.ids.tolist())) == len(markers.kinds)


def test_robot_state_node_publishes_the_tree_and_description_of_the_human_hand():
    h = NodeHarness(RobotStateNode, {"hand": "human", "origin": [0, 0.3, 0], "description_period_s": 1.0}, "human_tf")
    h.setup()
    rng = np.random.default_rng(3)
    for k in range(3):
        q = rng.uniform(HUMAN.lower, HUMAN.upper)
        h.send("joints", JointState(names=HUMAN.names, positions=q, hand="human"), stamp_ns=k * 600_000_000)
    tfs, descriptions = h.published["tf"], h.published["description"]
    assert len(tfs) == 3 and len(descriptions) == 2  # at 0 s and 1.2 s
    assert_tree_matches_urdf(tfs[-1], descriptions[0].data)
    assert tfs[-1].parents[0] == "world" and tfs[-1].children[0] == "human_tf/forearm"
    np.testing.assert_allclose(tfs[-1].translations[0], [0, 0.3, 0])
    h.send("joints", JointState(names=HUMAN.names, positions=q, hand="human"), stamp_ns=1_210_000_000)
    assert len(h.published["tf"]) == 3  # 10 ms after the last: above view_hz (30), skipped
    h.send("joints", JointState(names=["FFJ3"], positions=[0.1], hand="shadow"), stamp_ns=2_000_000_000)
    h.send("joints", JointState(names=["nope"], positions=[0.1], hand=""), stamp_ns=3_000_000_000)
    assert len(h.dropped) == 2 and "param hand" in h.dropped[0][1] and "nope" in h.dropped[1][1]


def test_simulator_node_publishes_tf_markers_and_a_repeated_description():
    h = NodeHarness(
        PybulletSimulatorNode, {"scene": "cap", "camera_hz": 0, "rate_hz": 10, "description_period_s": 0.5}, "sim"
    )
    h.setup()
    try:
        h.tick(8)
    finally:
        h.teardown()
    assert len(h.published["tf"]) == len(h.published["markers"]) == 8
    assert len(h.published["description"]) == 2  # at the first tick and 0.5 s later
    assert_tree_matches_urdf(h.published["tf"][-1], h.published["description"][0].data)
    assert h.published["markers"][-1].kinds == ["cylinder", "cylinder"]  # bottle and cap


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=24, max_size=24))
def test_robot_state_turns_any_finite_joint_angles_into_a_valid_tree(angles):
    h = NodeHarness(RobotStateNode, {"hand": "human"}).setup()
    h.send("joints", JointState(names=HUMAN.names, positions=angles, hand="human"))
    assert not h.dropped
    (tf,) = h.published["tf"]
    assert np.isfinite(tf.translations).all()  # tf passed the publisher's checks (unit quaternions)


def test_view_outputs_follow_view_hz_and_turn_off():
    rates = {}
    for view_hz in (5.0, 0.0):
        h = NodeHarness(PybulletSimulatorNode, {"camera_hz": 0, "rate_hz": 10, "view_hz": view_hz}, "sim").setup()
        try:
            h.tick(10)
        finally:
            h.teardown()
        rates[view_hz] = (len(h.published.get("tf", [])), len(h.published.get("description", [])))
    assert rates == {5.0: (5, 1), 0.0: (0, 0)}
