"""The simulator's grasp scene as the grasp family uses it: start posture, lying cylinder, camera (docs/grasping.md)."""

import numpy as np
import pybullet as p

from handflow.plugins.grasp.controller import SHADOW_PREGRASP
from handflow.plugins.simulator.simulation import Simulation


def test_hand_starts_in_the_given_posture():
    with Simulation(scene="grasp", scene_options={"object": "sphere", "start_posture": SHADOW_PREGRASP}) as sim:
        q = sim.joint_positions()
    np.testing.assert_allclose([q[sim.index[n]] for n in SHADOW_PREGRASP], list(SHADOW_PREGRASP.values()))


def test_cylinder_lies_across_the_fingers_and_yaw_turns_it():
    for yaw, axis in ((0.0, [0.0, 1.0, 0.0]), (90.0, [-1.0, 0.0, 0.0])):
        with Simulation(scene="grasp", scene_options={"object": "cylinder", "yaw_deg": yaw}) as sim:
            _, orn = p.getBasePositionAndOrientation(sim.scene.object_id, physicsClientId=sim.client)
            along = np.array(p.getMatrixFromQuaternion(orn)).reshape(3, 3)[:, 2]  # the cylinder's own axis
        assert abs(abs(along @ axis) - 1.0) < 1e-6


def test_camera_sees_the_object():
    with Simulation(scene="grasp", scene_options={"object": "box", "position": [0.03, 0.0]}) as sim:
        img = sim.render(96, 72).astype(int)
    orange = (img[..., 0] > 100) & (img[..., 0] > img[..., 1] + 60) & (img[..., 2] < 80)
    assert orange.mean() > 0.02  # the object fills part of the picture (the old camera was under the table)
