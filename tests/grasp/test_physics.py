"""Grasping in pybullet: the controller on real contacts, and a stable cylinder grasp (docs/grasping.md)."""

from pathlib import Path

import numpy as np
import pybullet as p
import pytest

from handflow.plugins.grasp.controller import HOLD, ExperienceGraspController
from handflow.plugins.grasp.episode import (
    CENTRED_POSE,
    EpisodeConfig,
    remove_table,
    run_grasp,
    set_damping,
    touched_segments,
)
from handflow.plugins.grasp.experience import ExperienceBase
from handflow.plugins.grasp.hand_layout import hand_layout
from handflow.plugins.hands.joints import HAND_MODELS
from handflow.plugins.simulator.scenes import GraspScene
from handflow.plugins.simulator.simulation import Simulation

MODEL = HAND_MODELS["shadow"]
LAYOUT = hand_layout("shadow")
SHIPPED_SOM = Path(__file__).resolve().parents[2] / "configs" / "grasp" / "experience" / "som_cylinder.npz"


@pytest.mark.slow
def test_held_fingers_keep_their_targets_on_real_contacts():
    ctl = ExperienceGraspController(LAYOUT, MODEL.lower, MODEL.upper)
    pose = CENTRED_POSE
    scene = GraspScene(
        object="cylinder",
        position=(pose.x, pose.y),
        gap_below_palm=pose.gap,
        yaw_deg=pose.yaw_deg,
        start_posture=ctl.config.pregrasp,
    )
    held_at: dict[str, np.ndarray] = {}
    with Simulation(scene=scene) as sim:
        remove_table(sim, scene)
        p.setGravity(0, 0, 0, physicsClientId=sim.client)
        for _ in range(150):
            targets = ctl.step(sim.joint_positions(), touched_segments(sim, ("table",)))
            if ctl.phase == "grip":
                break
            for f in LAYOUT.fingers:
                cols = [LAYOUT.names.index(j) for j in f.joints]
                if ctl.mode[f.name] == HOLD:
                    held_at.setdefault(f.name, targets[cols])
                    np.testing.assert_array_equal(targets[cols], held_at[f.name])
                else:
                    held_at.pop(f.name, None)
            sim.set_targets(ctl.names, targets)
            sim.step(4)
    assert held_at  # some finger was held over several cycles
    assert ctl.phase == "grip" and sum(m == HOLD for m in ctl.mode.values()) >= 3  # most fingers ended on a tip contact


@pytest.mark.slow
@pytest.mark.parametrize("experience", ["none", "cylinder_som"])
def test_centred_cylinder_is_grasped_stably(experience):
    base = ExperienceBase.load(SHIPPED_SOM) if experience == "cylinder_som" else None
    ctl = ExperienceGraspController(LAYOUT, MODEL.lower, MODEL.upper, base)
    result = run_grasp("cylinder", CENTRED_POSE, ctl, seed=0)
    assert result.valid and result.stable, result.summary()
    assert result.shift_m < 0.03 and result.quality > 0  # held under gravity + pushes, force closure
    assert "MF_distal" in result.touched and any(s.startswith("TH_") for s in result.touched)  # thumb opposes


@pytest.mark.slow
def test_grasp_node_drives_the_simulator_node(tmp_path):
    """The two node wrappers wired as in configs/grasp/experience_grasp.yaml, in-process, on the table."""
    from handflow.framework.testkit.harness import NodeHarness
    from handflow.plugins.grasp.node import ExperienceGraspNode
    from handflow.plugins.simulator.node import PybulletSimulatorNode

    sim = NodeHarness(
        PybulletSimulatorNode,
        {
            "scene": "grasp",
            "camera_hz": 0,
            "rate_hz": 60,
            "scene_options": {
                "object": "cylinder",
                "position": [CENTRED_POSE.x, CENTRED_POSE.y],
                "gap_below_palm": CENTRED_POSE.gap,
                "yaw_deg": CENTRED_POSE.yaw_deg,
            },
        },
    ).setup()
    grasp = NodeHarness(ExperienceGraspNode, {"experience": str(SHIPPED_SOM), "rate_hz": 60}).setup()
    try:
        for _ in range(240):
            sim.tick()
            grasp.send("joints", sim.published["joints"][-1])
            grasp.send("contacts", sim.published["contacts"][-1])
            grasp.tick()
            sim.send("targets", grasp.published["targets"][-1])
        phases = [s.state for s in grasp.published["status"]]
        assert "C" in phases and phases[-1] == "grip", grasp.node.controller.mode
        c = sim.published["contacts"][-1]
        on_object = {s for s, b in zip(c.segments, c.bodies) if b == "cylinder"}
        assert len(on_object) >= 3  # the fingers closed on the object, not on the table
    finally:
        sim.teardown()


def test_object_damping_makes_a_push_fade_and_is_validated():
    """Quasi-static grasping (EpisodeConfig.object_damping): a pushed object loses most of its speed in 1 s."""
    speed = {}
    for damping in (0.04, 0.99):
        scene = GraspScene(object="sphere", position=(0.1, 0.0))
        with Simulation(scene=scene) as sim:
            remove_table(sim, scene)
            p.setGravity(0, 0, 0, physicsClientId=sim.client)
            set_damping(sim, scene, damping)
            p.resetBaseVelocity(scene.object_id, [0.0, 0.5, 0.0], physicsClientId=sim.client)
            sim.step(240)
            speed[damping] = float(np.linalg.norm(p.getBaseVelocity(scene.object_id, physicsClientId=sim.client)[0]))
    assert speed[0.04] > 0.45 and speed[0.99] < 0.25  # Bullet multibody damping: dv/dt = −d·v·(1 + |v|)
    with pytest.raises(ValueError, match="object_damping"):
        EpisodeConfig(object_damping=1.0)
