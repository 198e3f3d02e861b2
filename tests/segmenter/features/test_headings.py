"""Heading channels: the direction of motion appended to every observation (docs/segmentation.md,
"Heading channels")."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from handflow.plugins.segmenter import (
    CLMSegmenter,
    CompetitiveLayerModel,
    OnlineCLMSegmenter,
    candidate_set,
    load_candidates,
    train_class_models,
)
from handflow.plugins.segmenter.cli import register_evaluate, register_train_classes
from handflow.plugins.segmenter.compatibility import reject_poor_fit
from handflow.plugins.segmenter.features import Headings
from handflow.plugins.segmenter.models import CandidateSet, Projection, save_class_models
from tests.conftest import run_command
from tests.segmenter.datasets.test_trajectories import write_csv_dataset


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 25), d=st.integers(1, 4), seed=st.integers(0, 9), softness=st.floats(0.0, 2.0))
def test_streamed_headings_equal_the_whole_sequence_headed(n, d, seed, softness):
    Y = np.random.default_rng(seed).normal(size=(n, d))
    headings = Headings(tuple(range(min(d, 2))), softness)
    stream = headings.stream()
    np.testing.assert_allclose(np.array([stream.push(y) for y in Y]), headings.transform(Y), atol=1e-12)


def test_a_heading_is_the_soft_unit_step_and_turns_round_backward():
    Y = np.array([[0.0, 0.0, 5.0], [3.0, 4.0, 5.0], [3.0, 4.0, 6.0], [3.0, 4.1, 7.0]])
    H = Headings((0, 1), softness=0.0).transform(Y)
    assert H.shape == (4, 5)
    np.testing.assert_allclose(H[:, :3], Y)  # the observations are kept as they are
    np.testing.assert_allclose(H[:, 3:], [[0, 0], [0.6, 0.8], [0, 0], [0, 1]], atol=1e-12)  # first: no step
    soft = Headings((0, 1), softness=0.1).transform(Y)
    assert soft[3, 4] == pytest.approx(0.1 / np.hypot(0.1, 0.1))  # a slow step fades out
    np.testing.assert_allclose(Headings((0, 1)).reversed(H)[:, 3:], -H[:, 3:])
    np.testing.assert_array_equal(Headings().transform(Y), Y)  # no channels: off


def test_fitted_softness_follows_the_median_step_and_bad_channels_are_refused():
    seq = np.cumsum(np.full((11, 2), [0.3, 0.4]), axis=0)  # every step 0.5 long
    assert Headings((0, 1)).fit([seq]).softness == pytest.approx(0.1)
    with pytest.raises(ValueError, match="does not exist"):
        Headings((2,)).fit([seq])
    with pytest.raises(ValueError, match="distinct"):
        Headings((0, 0))
    with pytest.raises(ValueError, match="the models head channel 1"):
        Headings((0, 1)).transform(np.zeros((3, 1)))
    with pytest.raises(ValueError, match="the models head channel 1"):
        Headings((0, 1)).stream().push(np.zeros(1))
    assert Headings.from_provenance(Headings((1, 0), 0.5).to_provenance()) == Headings((1, 0), 0.5)


json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-3, 5) | st.floats(allow_nan=True) | st.text(max_size=3),
    lambda inner: st.lists(inner, max_size=3),
    max_leaves=6,
)


@settings(max_examples=200, deadline=None)
@given(channels=json_values, softness=json_values)
def test_any_recorded_headings_load_or_are_refused_with_a_message(channels, softness):
    try:
        headings = Headings.from_provenance({"heading_channels": channels, "heading_softness": softness})
    except ValueError as exc:
        assert "retrain" in str(exc) or "heading" in str(exc)
    else:
        assert all(c >= 0 for c in headings.channels) and headings.softness >= 0


@pytest.fixture(scope="module")
def headed(synthetic):
    return candidate_set(train_class_models(synthetic, n_steps=100, random_state=0, headings=(0, 1)))


def test_headed_models_survive_save_and_load_and_mixed_sets_are_refused(tmp_path, headed, candidates, synthetic):
    save_class_models(headed, tmp_path)
    loaded = load_candidates(tmp_path)
    assert loaded.headings == headed.headings and loaded.headings.active and loaded.n_channels == 2
    Y = synthetic.test[0].data
    a, b = headed.project(Y), loaded.project(Y)
    np.testing.assert_allclose(a.errors, b.errors)
    np.testing.assert_allclose(a.reversed_errors, b.reversed_errors)
    with pytest.raises(ValueError, match="different heading channels"):
        CandidateSet({"A": headed.models["A"], "B": candidates.models["B"]})


def test_projection_rows_carry_the_reversed_errors(headed, synthetic):
    Y = synthetic.test[0].data
    proj = headed.project(Y)
    assert proj.reversed_errors.shape == proj.errors.shape
    part = Projection.concatenate([proj.take(slice(0, 5)), proj.take(np.arange(5, len(Y)))]).without("B")
    np.testing.assert_allclose(part.reversed_errors, np.delete(proj.reversed_errors, 1, axis=1))
    # a letter played backward is its own candidate's letter with the headings turned round
    own = headed.classes.index(synthetic.test[0].label)
    back = headed.project(Y[::-1])
    assert back.reversed_errors[:, own].mean() < 0.2 * back.errors[:, own].mean()


def test_the_fit_rule_seeks_the_best_fit_among_candidates_traversed_backward():
    errors = np.array([[0.1, 0.3]] * 4)
    labels = np.zeros(4, int)
    assert reject_poor_fit(labels, errors, 2.0).tolist() == [0] * 4
    backward = np.array([[0.5, 0.02]] * 4)  # candidate 1 backward fits 5× better than candidate 0 forward
    assert reject_poor_fit(labels, errors, 2.0, backward).tolist() == [-1] * 4


def test_headed_candidates_anneal_slower_by_default(headed, candidates):
    """Documented choice: the energy of headed candidates has near-equal minima, so their CLM
    anneals with η = 0.998 unless told otherwise; other candidates keep η = 0.98."""
    assert CLMSegmenter(headed)._solver().eta == 0.998
    assert OnlineCLMSegmenter(headed)._solver().eta == 0.998
    assert CLMSegmenter(candidates)._solver().eta == 0.98
    assert CLMSegmenter(headed, solver=CompetitiveLayerModel(eta=0.9))._solver().eta == 0.9


def test_headed_segmenters_reject_a_reversed_letter_in_batch_and_online_alike(headed, synthetic):
    a = next(t.data for t in synthetic.test if t.label == "A")
    Y = np.vstack([a, a[::-1], a])  # forward, reversed, forward: the middle letter must be rejected
    params = dict(history=10, background_factor=0.5, random_state=0, max_fit_ratio=2.0)
    batch = CLMSegmenter(headed, **params).fit_predict(Y)
    online = OnlineCLMSegmenter(headed, window=120, **params)
    labels = online.replay(Y)
    n = len(a)
    assert np.mean(batch[:n] == 0) > 0.9 and np.mean(batch[n : 2 * n] == -1) > 0.8
    assert np.mean(labels == batch) > 0.98
    # the node's path, sample by sample, sees the same projections as the whole stream
    online.reset()
    for y in Y:
        online.update(y)
    np.testing.assert_allclose(
        online._rows["reversed_errors"][: online.n], headed.project(Y).reversed_errors[-online.n :]
    )


def test_cli_heads_named_channels_and_refuses_unknown_ones(tmp_path, synthetic, capsys):
    data = write_csv_dataset(tmp_path / "letters", synthetic)
    assert (
        run_command(
            register_train_classes, [str(data), "--out", str(tmp_path / "m"), "--steps", "20", "--headings", "x,y"]
        )
        == 0
    )
    assert load_candidates(tmp_path / "m").headings.channels == (0, 1)
    assert run_command(register_train_classes, [str(data), "--out", str(tmp_path / "x"), "--headings", "speed"]) == 2
    assert "--headings: no channel 'speed'" in capsys.readouterr().err
    np.savez(tmp_path / "c.npz", class_names=np.array(["a"]), X_r=np.zeros((4, 2)), y_r=np.zeros(4, int))
    assert run_command(register_evaluate, [str(tmp_path / "c.npz"), "--headings", "0"]) == 2
    assert "--headings applies to labelled trajectories" in capsys.readouterr().err


def test_the_node_heads_each_sample_and_rejects_a_reversed_letter_live(tmp_path, headed, synthetic):
    from handflow.framework.messages import Array
    from handflow.framework.testkit.harness import NodeHarness
    from handflow.plugins.segmenter.nodes import UNKNOWN, OnlineCLMNode

    folder = save_class_models(headed, tmp_path)
    a = next(t.data for t in synthetic.test if t.label == "A")
    params = {"models": str(folder), "history": 10, "background_factor": 0.5, "max_fit_ratio": 2.0}
    h = NodeHarness(OnlineCLMNode, params).setup()
    for i, y in enumerate(np.vstack([a, a[::-1]])):
        h.send("array", Array(data=y), stamp_ns=i * 10_000_000)
    h.node.publish_events(h.node.segmenter.finish(), stamp=0)
    labels = [m.label for m in h.published["labels"]]
    for e in h.published["events"]:
        if e.kind == "revision":
            labels[e.start_index : e.end_index + 1] = [e.label] * (e.end_index - e.start_index + 1)
    n = len(a)
    assert sum(label == "A" for label in labels[:n]) > 0.9 * n
    assert sum(label == UNKNOWN for label in labels[n:]) > 0.8 * n
    with pytest.raises(ValueError, match="heading channels"):
        NodeHarness(OnlineCLMNode, {"models": str(folder), "running_normalisation_frames": 10}).setup()


def test_ukr_only_streams_headed_observations_as_the_batch_projects_them(headed, synthetic):
    from handflow.plugins.segmenter import UKROnlyRecognizer

    Y = synthetic.test[0].data
    batch = UKROnlyRecognizer(headed, history=5).predict(Y)
    live = UKROnlyRecognizer(headed, history=5)
    np.testing.assert_array_equal([live.update(y)[0] for y in Y], batch)
