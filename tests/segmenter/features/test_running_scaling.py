"""Causal per-recording standardisation (docs/segmentation.md, "Per-recording normalisation")."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from sklearn.exceptions import NotFittedError

from handflow.framework.messages import Array
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.segmenter import save_class_models, train_class_models
from handflow.plugins.segmenter.cli import register_evaluate
from handflow.plugins.segmenter.datasets import Recording
from handflow.plugins.segmenter.evaluation import RecordingsEvaluator
from handflow.plugins.segmenter.evaluation._recordings import _zscore
from handflow.plugins.segmenter.features import ChannelScaling, RunningStandardizer
from handflow.plugins.segmenter.nodes import OnlineCLMNode
from tests.conftest import run_command
from tests.segmenter.datasets.test_recordings import _synthetic_recordings

TRAIN = np.random.default_rng(0).normal([3.0, -1.0], [2.0, 0.5], size=(400, 2))


def _fitted(**params) -> RunningStandardizer:
    return RunningStandardizer(**params).fit(TRAIN)


def test_output_at_t_does_not_depend_on_later_frames():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(300, 2))
    later = X.copy()
    later[121:] = rng.normal(50.0, 9.0, size=(179, 2))
    s = _fitted()
    np.testing.assert_array_equal(s.transform(X)[:121], s.transform(later)[:121])
    assert not np.allclose(s.transform(X)[121:], s.transform(later)[121:])


@settings(max_examples=80, deadline=None)
@given(
    X=arrays(
        np.float64,
        st.tuples(st.integers(1, 40), st.just(2)),
        elements=st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False),
    ),
    prior_frames=st.floats(0.01, 1000.0),
    variance_floor=st.floats(1e-6, 1.0),
)
def test_streaming_equals_the_batch(X, prior_frames, variance_floor):
    s = _fitted(prior_frames=prior_frames, variance_floor=variance_floor)
    stream = s.stream()
    np.testing.assert_array_equal(np.array([stream.update(x) for x in X]), s.transform(X))


def test_first_frame_is_standardised_by_the_prior():
    s = _fitted()
    x0 = s.mean_ + 0.5 * s.scale_
    np.testing.assert_allclose(s.transform(x0[None])[0], 0.5, rtol=0.01)
    np.testing.assert_allclose(s.mean_, TRAIN.mean(axis=0))
    np.testing.assert_allclose(s.scale_, TRAIN.std(axis=0))


def test_a_long_recording_loses_its_constant_offset():
    s = _fitted()
    X = np.random.default_rng(2).normal(
        s.mean_ + 5.0 * s.scale_, s.scale_, size=(20_000, 2)
    )  # another person: 5 sd off
    assert np.all(ChannelScaling.fitted(s.mean_, s.scale_).transform(X)[-1000:].mean(axis=0) > 4.5)
    tail = s.transform(X)[-1000:]
    assert np.all(np.abs(tail.mean(axis=0)) < 0.15) and np.all(np.abs(tail.std(axis=0) - 1.0) < 0.15)


def test_the_variance_floor_keeps_a_still_channel_from_turning_into_noise():
    s = _fitted(prior_frames=1)
    X = s.mean_ + 1e-9 * np.random.default_rng(3).normal(size=(5000, 2))  # a channel that stops moving
    assert np.abs(s.transform(X)[1000:]).max() < 1e-7  # at most 10x the training scaling (floor 0.01)


@pytest.mark.parametrize(
    ("X", "needle"),
    [
        (np.array([[1.0, np.nan]]), "NaN/inf"),
        (np.array([[1.0, np.inf]]), "NaN/inf"),
        (np.ones(3), "frames, channels"),
        (np.zeros((0, 2)), "at least one frame"),
        ([["a", "b"]], "not numeric"),
        ([[1, 10**400]], "not numeric"),  # an integer no float holds
    ],
)
def test_bad_training_frames_are_refused_with_a_reason(X, needle):
    with pytest.raises(ValueError, match=needle):
        RunningStandardizer().fit(X)


@pytest.mark.parametrize("params", [{"prior_frames": 0}, {"prior_frames": np.nan}, {"variance_floor": -1.0}])
def test_bad_hyper_parameters_are_refused_by_fit(params):
    with pytest.raises(ValueError, match=next(iter(params))):
        RunningStandardizer(**params).fit(TRAIN)


def test_transform_and_stream_check_their_input():
    with pytest.raises(NotFittedError, match="fit"):
        RunningStandardizer().transform(TRAIN)
    s = _fitted()
    with pytest.raises(ValueError, match="3 channels, but the prior has 2"):
        s.transform(np.zeros((4, 3)))
    with pytest.raises(ValueError, match="too far"):
        s.transform(np.full((2, 2), 1e300))
    X = np.random.default_rng(4).normal(size=(6, 2))
    stream = s.stream()
    out = [stream.update(x) for x in X[:3]]
    for bad in ([np.nan, 0.0], [1e300, 0.0], [1.0]):  # refused, and the stream is as it was
        with pytest.raises(ValueError):
            stream.update(bad)
    out += [stream.update(x) for x in X[3:]]
    np.testing.assert_array_equal(out, s.transform(X))


def test_recording_normalisation_applies_the_training_prior_to_every_recording():
    (X0, y0), (X1, y1) = _synthetic_recordings(0), _synthetic_recordings(1)
    train, held = [Recording("r0", X0, y0)], Recording("r1", 3.0 + X1, y1)
    out = _zscore(train, [train[0], held], "recording")
    s = RunningStandardizer().fit(X0)
    np.testing.assert_array_equal(out[0].X, s.transform(X0))
    np.testing.assert_array_equal(out[1].X, s.transform(held.X))
    np.testing.assert_allclose(_zscore(train, [held])[0].X, (held.X - X0.mean(axis=0)) / X0.std(axis=0))
    with pytest.raises(ValueError, match="normalise must be one of"):
        RecordingsEvaluator(None, normalise="person")


def test_cli_reports_the_normalisation_in_json(tmp_path, capsys):
    arrays_ = {"class_names": np.array(["a", "b", "c"])}
    for k in range(3):
        X, arrays_[f"y_r{k}"] = _synthetic_recordings(k)
        arrays_[f"X_r{k}"] = X + k  # each "person" shifted
    np.savez(tmp_path / "s.npz", **arrays_)
    argv = [str(tmp_path / "s.npz"), "--methods", "dtw_1nn", "--quick", "--json", "--normalise", "recording"]
    assert run_command(register_evaluate, [*argv, "--pseudo-unknowns", "drop"]) == 0
    parameters = json.loads(capsys.readouterr().out)["parameters"]
    normalisation = parameters["normalisation"]
    assert normalisation["mode"] == "recording" and normalisation["prior_frames"] == 200
    assert parameters["pseudo_unknowns"] == "drop"
    for option in (["--normalise", "recording"], ["--pseudo-unknowns", "drop"]):
        assert run_command(register_evaluate, [str(tmp_path), *option]) == 2  # not continuous recordings
        assert "apply to continuous recordings" in capsys.readouterr().err
    with pytest.raises(ValueError, match="pseudo_unknowns must be one of"):
        RecordingsEvaluator(None, pseudo_unknowns="guess")


@pytest.fixture(scope="module")
def letter_models(tmp_path_factory, ukr_models):
    return save_class_models(ukr_models, tmp_path_factory.mktemp("models"))


def test_online_node_applies_the_running_normalisation_live(letter_models, two_letters, ukr_models):
    """The node with the running normalisation labels a stream exactly as the node without it labels
    the stream standardised beforehand (in raw units); a bad observation is dropped without a trace."""
    Y, _ = two_letters
    Y = Y[:80] + 0.3  # another writer, shifted
    params = {"models": str(letter_models), "window": 40, "history": 5, "block": 0}
    live = NodeHarness(OnlineCLMNode, {**params, "running_normalisation_frames": 50}).setup()
    for k, y in enumerate(Y):
        live.send("array", Array(data=y))
        if k == 10:
            live.send("array", Array(data=[np.nan, 0.0]))
    scaling = ChannelScaling.from_model(next(iter(ukr_models.values())))
    prior = RunningStandardizer(prior_frames=50).set_prior(scaling.offset_, scaling.scale_)
    before = NodeHarness(OnlineCLMNode, params).setup()
    for y in scaling.inverse_transform(prior.transform(Y)):
        before.send("array", Array(data=y))
    assert len(live.dropped) == 1
    assert [m.label for m in live.published["labels"]] == [m.label for m in before.published["labels"]]


def test_online_node_refuses_running_normalisation_without_a_scaling(tmp_path, synthetic):
    raw = save_class_models(train_class_models(synthetic.restrict(["A"]), n_steps=10, scaling="none"), tmp_path)
    with pytest.raises(ValueError, match="channel scaling"):
        NodeHarness(OnlineCLMNode, {"models": str(raw), "running_normalisation_frames": 10}).setup()
    with pytest.raises(Exception, match="needs source 'ukr'"):
        NodeHarness(OnlineCLMNode, {"source": "dtw", "scorer": "s.npz", "running_normalisation_frames": 10})
