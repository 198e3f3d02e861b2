"""Ball scene: the open-loop motion really swaps the balls; scheduled pushes; the scene hook."""

import numpy as np
import pytest

from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.demo.ball_swap import BallSwapMotion, keyframes, run_open_loop_swaps
from handflow.plugins.simulator.metrics import count_swaps
from handflow.plugins.simulator.node import PybulletSimulatorNode
from handflow.plugins.simulator.scenes import BallsScene, Scene
from handflow.plugins.simulator.simulation import Simulation


@pytest.mark.parametrize("seed", [0, 3])
def test_open_loop_motion_swaps_the_balls_in_the_cupped_palm(seed):
    pts, _ = run_open_loop_swaps(8.0, seed, {"jitter": 0.004})
    assert count_swaps(pts[:, 0], pts[:, 1]) >= 3  # four hand cycles: one swap per cycle
    centre = np.array(BallsScene().cup_centre)
    assert np.linalg.norm(pts - centre, axis=2).max() < 0.035  # both balls stay in the palm


def test_without_the_raking_fingers_nothing_swaps():
    still = BallSwapMotion(rake_mcp=((0.0, 0.1),), rake_pip=((0.0, 1.4),))
    np.testing.assert_allclose(still.targets([0.1, 0.6]), still.targets([0.3, 0.9]))
    motion = BallSwapMotion()
    assert not np.allclose(motion.targets(0.0), motion.targets(0.35))


def test_keyframes_interpolate_periodically_and_reject_bad_keys():
    keys = ((0.0, 0.0), (0.5, 1.0))
    np.testing.assert_allclose(keyframes([0.0, 0.25, 0.5, 0.75, 1.0, 1.5], keys), [0, 0.5, 1, 0.5, 0, 1], atol=1e-12)
    with pytest.raises(ValueError, match="increasing phases"):
        keyframes(0.1, ((0.5, 0.0), (0.2, 1.0)))


def test_a_push_fires_once_against_the_ball_motion_and_is_reported():
    with Simulation("gifu", "balls", {"pushes": [[1.0, 0.3]]}, seed=0) as sim:
        sim.step(240)  # the balls settle; the step starting at t = 1.0 s is the first one at or after the push time
        assert sim.scene_state()["pushes_done"] == 0
        sim.step(1)
        v = sim.scene.palm_plane_velocities(sim.client)
        assert sim.scene_state()["pushes_done"] == 1
        sim.step(100)
        assert sim.scene_state()["pushes_done"] == 1
    # balls at rest: ball 1 is pushed along palm -z (towards the wrist) at about the set speed
    along = sim.scene.hand_rotation().apply([0.0, 0.0, -1.0])
    assert v[0] @ along == pytest.approx(0.3, abs=0.05)


def test_push_sets_a_ball_velocity_and_checks_the_index():
    with Simulation("gifu", "balls", seed=0) as sim:
        sim.scene.push(sim.client, 1, [0.0, 0.2, 0.0])
        assert sim.scene.palm_plane_velocities(sim.client)[1] @ [0, 1, 0] > 0.1
        with pytest.raises(ValueError, match="ball_index"):
            sim.scene.push(sim.client, 2, [0, 0, 0])


def test_bad_pushes_are_rejected_with_the_expected_form():
    with pytest.raises(ValueError, match=r"\[time_s, speed_m_s\]"):
        BallsScene(pushes=[[1.0]])
    with pytest.raises(ValueError, match=">= 0"):
        BallsScene(pushes=[[-1.0, 0.2]])


def test_simulation_calls_the_scene_hook_before_every_step():
    times = []

    class Recording(Scene):
        def before_step(self, client, t):
            times.append(t)

    scene = Recording()
    with Simulation("gifu", scene, physics_hz=100) as sim:
        sim.step(3)
    assert times == pytest.approx([0.0, 0.01, 0.02])


def test_node_scene_options_schedule_pushes():
    h = NodeHarness(
        PybulletSimulatorNode,
        {"hand": "gifu", "scene": "balls", "camera_hz": 0, "rate_hz": 20, "scene_options": {"pushes": [[0.1, 0.2]]}},
    ).setup()
    try:
        h.tick(5)
        scene = h.published["scene"][-1]
        assert scene.data[scene.names.index("pushes_done")] == 1
    finally:
        h.teardown()


def test_a_turn_rotates_the_ball_pair_back_once_and_stops_the_balls():
    from handflow.plugins.simulator.metrics import pair_rotation

    with Simulation("gifu", "balls", {"turns": [[0.5, 90.0]]}, seed=0) as sim:
        sim.step(119)
        before = sim.scene.palm_plane_positions(sim.client)
        centre = np.array(sim.scene.cup_centre)
        sim.step(2)  # the step starting at t = 0.5 s turns the pair
        after = sim.scene.palm_plane_positions(sim.client)
        assert sim.scene_state()["turns_done"] == 1
        sim.step(240)
        assert sim.scene_state()["turns_done"] == 1
    turned = pair_rotation(np.array([before[0], after[0]]), np.array([before[1], after[1]]))[1]
    assert turned == pytest.approx(np.pi / 2, abs=0.05)  # counter-clockwise = back
    np.testing.assert_allclose(
        np.linalg.norm(after - centre, axis=1), np.linalg.norm(before - centre, axis=1), atol=2e-3
    )


def test_bad_turns_are_rejected_with_the_expected_form():
    with pytest.raises(ValueError, match=r"\[time_s, angle_deg\]"):
        BallsScene(turns=[[1.0]])
    with pytest.raises(ValueError, match="-180 <= angle_deg <= 180"):
        BallsScene(turns=[[1.0, 270.0]])


def test_a_hold_keeps_both_balls_in_place_for_its_duration_then_releases_them():
    from handflow.plugins.hands.joints import GIFU

    motion = BallSwapMotion()
    with Simulation("gifu", "balls", {"holds": [[0.5, 0.5]]}, seed=0) as sim:

        def run(steps):
            for _ in range(steps):
                sim.set_targets(GIFU.names, motion.targets((sim.time % 2.0) / 2.0)[0])
                sim.step(1)

        run(121)  # the step starting at t = 0.5 s starts the hold
        held = sim.scene.palm_plane_positions(sim.client)
        assert sim.scene_state()["holds_done"] == 1
        run(100)  # the hand goes on moving; the balls stay
        # reset before every physics step: a held ball strays < 1.5 mm within one step
        np.testing.assert_allclose(sim.scene.palm_plane_positions(sim.client), held, atol=1.5e-3)
        run(480)  # released: the hand moves the balls again
        assert np.abs(sim.scene.palm_plane_positions(sim.client) - held).max() > 2e-3


def test_bad_holds_are_rejected_with_the_expected_form():
    with pytest.raises(ValueError, match=r"\[time_s, duration_s\]"):
        BallsScene(holds=[[1.0]])
    with pytest.raises(ValueError, match="0 < duration_s <= 10"):
        BallsScene(holds=[[1.0, 0.0]])
