"""Controller nodes through NodeHarness: commands, fail-safe, replay of training data."""

import numpy as np
import pytest

from handflow.framework.files.mcap_reader import read_messages
from handflow.framework.files.mcap_writer import McapWriter
from handflow.framework.messages import Contacts, JointState, Points2D
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.hands.joints import GIFU, SHADOW
from handflow.plugins.manifold import InvalidInputError
from handflow.plugins.manipulation.nodes import ClosedLoopNode, FeedbackInitNode, OpenLoopNode


def _open_hand(msg, model):
    return msg.names == model.names and np.allclose(msg.positions, model.clip(np.zeros(len(model))))


def test_open_loop_node_publishes_f_of_the_latent_it_reports(cap_manifold, manifold_file):
    path = manifold_file(cap_manifold)
    h = NodeHarness(OpenLoopNode, {"manifold": str(path), "latent": [0.3, 2.0], "delta": 0.01, "rate_hz": 50}).setup()
    h.tick(5)
    targets, latents = h.published["targets"], h.published["latent"]
    assert len(targets) == 5 and targets[0].names == cap_manifold.joint_names
    for t, x in zip(targets, latents):
        assert np.allclose(t.positions, cap_manifold.posture(x.coords))
    assert np.allclose([x.coords[0] for x in latents], 0.3 + 0.01 * np.arange(1, 6))
    assert _open_hand(h.node.safe_output()["targets"], SHADOW)


def test_missing_or_plain_manifold_file_is_a_clear_error(tmp_path, cap_manifold):
    h = NodeHarness(OpenLoopNode, {"manifold": str(tmp_path / "none.npz"), "latent": [0, 2]})
    with pytest.raises(InvalidInputError, match="not found; train it first"):
        h.setup()
    cap_manifold.model.save(tmp_path / "plain.npz")
    h = NodeHarness(OpenLoopNode, {"manifold": str(tmp_path / "plain.npz"), "latent": [0, 2]})
    with pytest.raises(InvalidInputError, match="without manipulation metadata"):
        h.setup()


def _contacts(*fingers):
    segs = [f"{f}_distal" for f in fingers]
    return Contacts(segments=segs, bodies=["cap"] * len(segs), forces=np.ones(len(segs)))


def test_feedback_init_node_closes_until_contact_then_turns_and_fails_safe(cap_manifold, manifold_file):
    path = manifold_file(cap_manifold)
    h = NodeHarness(
        FeedbackInitNode,
        {"manifold": str(path), "rate_hz": 20, "radius_step": 0.05, "approach_s": 0.1, "stale_after_s": 0.3},
    ).setup()
    for _ in range(10):
        h.send("contacts", _contacts("TH", "FF"))  # middle finger missing: keep closing
        h.tick()
    r_closing = h.published["latent"][-1].coords[1]
    assert r_closing < 3.5
    h.send("contacts", _contacts("TH", "FF", "MF", "RF"))
    h.tick(3)
    radii = [x.coords[1] for x in h.published["latent"][-3:]]
    assert radii == [radii[0]] * 3 and h.node.controller.grasp_complete
    n = len(h.published["targets"])
    h.tick(10)  # 0.5 s without contacts message
    assert _open_hand(h.published["targets"][-1], SHADOW)
    assert len(h.published["targets"]) == n + 10
    h.send("contacts", _contacts())
    h.tick()
    assert h.published["targets"][-1].names == cap_manifold.joint_names


def test_feedback_init_node_grasp_variant_projects_the_posture(cap_manifold, manifold_file):
    from tests.manipulation.synthetic import posture

    path = manifold_file(cap_manifold)
    h = NodeHarness(FeedbackInitNode, {"manifold": str(path), "init": "grasp", "rate_hz": 20}).setup()
    h.send("contacts", _contacts())
    h.tick(2)
    assert not h.published["targets"]  # waits for the grasp posture
    y = posture([0.45], 2.5)[0]
    h.send("grasp", JointState(names=cap_manifold.names, positions=y, hand="shadow"))
    h.send("contacts", _contacts())
    h.tick()
    assert abs(h.published["latent"][-1].coords[1] - 2.5) < 0.2


def test_closed_loop_phase_follows_a_replayed_recording_of_its_training_data(ball_manifold, manifold_file, tmp_path):
    path = manifold_file(ball_manifold)
    model = ball_manifold.model
    rec = tmp_path / "balls.mcap"
    rng = np.random.default_rng(1)
    with McapWriter(rec) as w:
        for i, y in enumerate(model.Y_):
            pts = y[4:].reshape(2, 2)[rng.permutation(2)]  # tracker order is arbitrary
            w.write("handflow/test/tracker/balls", Points2D(points=pts, valid=[True, True], ids=[0, 1]), i * 50_000_000)
    h = NodeHarness(
        ClosedLoopNode, {"manifold": str(path), "k": 3, "delta": 0.05, "rate_hz": 20, "tolerance": 0.0}
    ).setup()
    errors = []
    for (_topic, msg, t), x in zip(read_messages(rec), model.latents_):
        h.send("balls", msg, stamp_ns=t)
        commanded = h.published["latent"][-1].coords  # first planned latent x̂ + Δ
        d = np.mod(commanded[0] - 0.05 * ball_manifold.time_sign - x[0], np.pi / 2)
        errors.append(min(d, np.pi / 2 - d))
        assert np.allclose(h.published["targets"][-1].positions, ball_manifold.posture(commanded))
    assert len(errors) == len(model.Y_) and np.median(errors) < 0.03 and np.max(errors) < 0.15


def test_closed_loop_node_actuates_the_plan_in_order_then_fails_safe(ball_manifold, manifold_file):
    path = manifold_file(ball_manifold)
    h = NodeHarness(
        ClosedLoopNode, {"manifold": str(path), "k": 3, "delta": 0.05, "rate_hz": 20, "stale_after_s": 0.2}
    ).setup()
    y = ball_manifold.model.Y_[0]
    h.send("balls", Points2D(points=y[4:].reshape(2, 2), valid=[True, True]))
    h.tick(2)
    t = [x.coords[0] for x in h.published["latent"]]
    assert np.allclose(np.mod(ball_manifold.time_sign * np.diff(t), np.pi), 0.05)
    h.send("balls", Points2D(points=np.full((2, 2), np.nan), valid=[False, False]))
    h.tick(4)  # plan used up, no valid balls
    assert _open_hand(h.published["targets"][-1], GIFU)


def test_controllers_take_speed_closing_step_and_horizon_while_running(cap_manifold, ball_manifold, manifold_file):
    """docs/tuning.md: delta, radius_step and k are live; the latent advances by the new delta at once."""
    h = NodeHarness(
        OpenLoopNode, {"manifold": str(manifold_file(cap_manifold)), "latent": [0.3, 2.0], "delta": 0.01, "rate_hz": 50}
    ).setup()
    h.tick(2)
    h.set_param("delta", 0.03)
    h.tick(2)
    assert np.allclose([x.coords[0] for x in h.published["latent"]], [0.31, 0.32, 0.35, 0.38])
    closing = NodeHarness(FeedbackInitNode, {"manifold": str(manifold_file(cap_manifold)), "radius_step": 0.05}).setup()
    direction = np.sign(closing.node.controller.radius_step)
    closing.set_param("radius_step", 0.02)
    assert closing.node.controller.radius_step == pytest.approx(0.02 * direction)
    closed = NodeHarness(ClosedLoopNode, {"manifold": str(manifold_file(ball_manifold, "b.npz")), "k": 3}).setup()
    closed.set_param("k", 6)
    assert closed.node.controller.k == 6
