"""Colour-blob tracker on images rendered by the simulator, against projected ground truth."""

import numpy as np
import pybullet as p
import pytest

from handflow.framework.messages import Image
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.simulator.simulation import Simulation
from handflow.plugins.tracker.blobs import BallTracker, normalise_points
from handflow.plugins.tracker.node import ColorBlobTrackerNode

ERROR_BOUND = 0.02
"""Documented accuracy bound (normalised units; marks are 2 apart) for unoccluded balls at 320×240."""
W, H = 320, 240


@pytest.fixture(scope="module")
def sim():
    s = Simulation("gifu", "balls", seed=0)
    s.step(120)
    yield s
    s.close()


def _place(sim, local):
    for ball, pos in zip(sim.scene.balls, sim.scene.palm_to_world(local)):
        p.resetBasePositionAndOrientation(ball, pos, [0, 0, 0, 1], physicsClientId=sim.client)


def _truth(sim):
    cam = sim.scene.camera()
    marks = cam.project(sim.scene.mark_positions(), W, H)
    return normalise_points(cam.project(sim.scene.ball_positions(sim.client), W, H), marks[0], marks[1])


def test_normalisation_puts_the_marks_at_minus_one_and_one():
    a, b = np.array([200.0, 170.0]), np.array([120.0, 160.0])
    out = normalise_points(np.vstack([a, b, (a + b) / 2]), a, b)
    np.testing.assert_allclose(out, [[-1, 0], [1, 0], [0, 0]], atol=1e-12)


def test_tracker_error_against_projected_ground_truth_is_within_the_bound(sim):
    rng = np.random.default_rng(3)
    surface = -sim.scene.palm_thickness / 2 - sim.scene.ball_radius - 0.001
    errors = []
    tracker = BallTracker()
    while len(errors) < 8:
        local = np.c_[rng.uniform(-0.03, 0.03, 2), [surface] * 2, rng.uniform(0.05, 0.08, 2)]
        if np.linalg.norm(local[0] - local[1]) < 2 * sim.scene.ball_radius + 0.002:
            continue
        _place(sim, local)
        res = tracker.update(sim.render(W, H))
        assert res.balls_valid.all() and res.marks_valid.all()
        truth = _truth(sim)
        d = np.linalg.norm(res.balls[:, None] - truth[None], axis=2)
        errors.append(min(d[0, 0] + d[1, 1], d[0, 1] + d[1, 0]) / 2)
    assert max(errors) < ERROR_BOUND


def test_touching_balls_are_split_into_two(sim):
    surface = -sim.scene.palm_thickness / 2 - sim.scene.ball_radius - 0.001
    _place(sim, [[0.0201, surface, 0.065], [-0.0201, surface, 0.065]])
    res = BallTracker().update(sim.render(W, H))
    assert res.balls_valid.all()
    truth = _truth(sim)
    d = np.linalg.norm(res.balls[:, None] - truth[None], axis=2)
    assert min(d[0, 0] + d[1, 1], d[0, 1] + d[1, 0]) / 2 < 2 * ERROR_BOUND


def test_a_hidden_ball_is_reported_missing_and_ids_stay_with_their_balls(sim):
    surface = -sim.scene.palm_thickness / 2 - sim.scene.ball_radius - 0.001
    tracker = BallTracker()
    _place(sim, [[0.025, surface, 0.07], [-0.025, surface, 0.06]])
    first = tracker.update(sim.render(W, H))
    right_id = first.ids[np.argmin(first.balls[:, 0])]  # ball on the mark-A (thumb) side
    _place(sim, [[0.022, surface, 0.072], [-0.025, -surface + 0.01, 0.06]])  # second ball under the palm
    hidden = tracker.update(sim.render(W, H))
    assert hidden.balls_valid.sum() == 1
    assert np.isnan(hidden.balls[~hidden.balls_valid]).all()
    assert hidden.ids[hidden.balls_valid][0] == right_id
    _place(sim, [[0.02, surface, 0.074], [-0.025, surface, 0.058]])
    back = tracker.update(sim.render(W, H))
    assert back.balls_valid.all() and set(back.ids) == set(first.ids)


def test_without_marks_no_ball_is_normalised():
    img = np.zeros((60, 80, 3), np.uint8)
    img[20:30, 20:30] = (240, 190, 10)  # one yellow ball, no marks
    res = BallTracker().update(img)
    assert not res.balls_valid.any() and not res.marks_valid.any()


def test_node_publishes_balls_and_marks(sim):
    h = NodeHarness(ColorBlobTrackerNode, {}).setup()
    surface = -sim.scene.palm_thickness / 2 - sim.scene.ball_radius - 0.001
    _place(sim, [[0.025, surface, 0.07], [-0.025, surface, 0.06]])
    h.send("image", Image.from_array(sim.render(W, H)), stamp_ns=123)
    balls, marks = h.published["balls"][-1], h.published["marks"][-1]
    assert balls.valid.all() and balls.points.shape == (2, 2) and balls.header.stamp_ns == 123
    assert marks.valid.all() and list(marks.ids) == [0, 1]
    h.send("image", Image(width=2, height=2, encoding="mono16", step=4, data=bytes(8)))  # dropped
    assert "rgb8" in h.dropped[0][1]
