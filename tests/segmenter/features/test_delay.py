"""Delay-embedded class manifolds with relative reconstruction evidence (docs/segmentation.md,
"Continuous recordings")."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from handflow.plugins.segmenter import CLMSegmenter, OnlineCLMSegmenter
from handflow.plugins.segmenter.evaluation import REGISTRY
from handflow.plugins.segmenter.features import DelayEmbedding, Derived
from tests.segmenter.datasets.test_recordings import _synthetic_recordings, held_out_class_evaluation


@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(1, 30),
    d=st.integers(1, 3),
    window=st.integers(1, 6),
    step=st.integers(1, 3),
    seed=st.integers(0, 9),
)
def test_streamed_embedding_equals_the_whole_recording_embedded(n, d, window, step, seed):
    X = np.random.default_rng(seed).normal(size=(n, d))
    delay = DelayEmbedding(window, step)
    stream = delay.stream()
    np.testing.assert_array_equal(np.array([stream.push(x) for x in X]), delay.transform(X))


def test_embedding_is_causal_and_complete_windows_lie_inside_the_segment():
    X = np.arange(10.0)[:, None]
    E = DelayEmbedding(3, 2).transform(X)
    assert E.shape == (10, 3)
    assert E[6].tolist() == [2.0, 4.0, 6.0]  # frames t−4, t−2, t, oldest first
    assert E[1].tolist() == [0.0, 0.0, 1.0]  # the first frame stands in for the missing past
    assert DelayEmbedding(3, 2).complete(X)[0].tolist() == [0.0, 2.0, 4.0]
    with pytest.raises(ValueError, match="window and step"):
        DelayEmbedding(0)


@pytest.fixture(scope="module")
def fitted():
    X, y = _synthetic_recordings(0)
    method = REGISTRY["ukr_clm"]
    return method, method.fit({c: [X[y == c]] for c in (0, 1, 2)}, {"delay": 4, "history": 10}, seed=0), X, y


def test_delay_models_label_frames_and_the_null_model_rejects(fitted):
    method, fit, X, y = fitted
    assert fit.model.delay == DelayEmbedding(4) and fit.model.evidence_temperature > 0
    state = method.prepare(fit, X)
    assert state.errors.shape == (len(X), 3)
    kept = method.labels(fit, state, reject=0.0)
    assert np.mean(kept == y) > 0.8 and not np.any(kept == -1)  # factor 0: no background
    assert np.all(method.labels(fit, state, reject=1e6) == -1)  # the null model explains everything better
    dropped = method.labels(fit, state, reject=1.0, drop=2)
    assert not np.any(dropped == 2)
    assert np.mean(dropped[y == 2] == -1) > np.mean(dropped[y != 2] == -1)  # the left-out class goes to the background


def test_errors_share_one_metric_across_class_models(fitted):
    _, fit, _, _ = fitted
    variances = [c.model.train_variance_ for c in fit.model.models.values()]
    references = {c.error_reference for c in fit.model.models.values()}
    assert all(np.array_equal(v, variances[0]) for v in variances) and len(references) == 1
    assert len(fit.model.own_errors) == 3 and np.all(fit.model.own_errors > 0)


def test_online_relative_segmenter_equals_the_batch_and_embeds_sample_by_sample(fitted):
    method, fit, X, _ = fitted
    batch = method.segmenter(fit.model, 0.0, history=10)
    params = {k: batch.get_params()[k] for k in ("history", "background_factor", "reconstruction", "random_state")}
    online = OnlineCLMSegmenter(fit.model, window=len(X), block=0, **params)  # one window: the batch's problem
    by_update = []
    for x in X:
        up = online.update(x)
        by_update.append(up.label)
    replayed = OnlineCLMSegmenter(fit.model, window=len(X), block=0, **params).replay(X)
    assert np.mean(replayed == CLMSegmenter(fit.model, **params).fit_predict(X)) >= 0.99
    assert len(by_update) == len(X)
    with pytest.raises(ValueError, match="NaN"):
        online.update(np.full(X.shape[1], np.nan))
    with pytest.raises(ValueError, match="reconstruction"):
        CLMSegmenter(fit.model, reconstruction="other").fit_predict(X)


def test_saved_delay_models_keep_their_embedding(fitted, tmp_path):
    from handflow.plugins.segmenter.models import load_candidates, save_class_models

    _, fit, X, _ = fitted
    save_class_models(fit.model, tmp_path)
    loaded = load_candidates(tmp_path)
    assert loaded.delay == fit.model.delay
    assert loaded.evidence_temperature == pytest.approx(fit.model.evidence_temperature)
    np.testing.assert_allclose(loaded.own_errors, fit.model.own_errors)


def test_online_block_runs_over_a_sliding_window_agree_with_the_batch(fitted):
    """Regression: the relative bands are handed to a block run that goes on while the window
    slides; it must not see the window's bands shift under it."""
    method, fit, X, _ = fitted
    params = {"history": 10, "background_factor": 0.0, "reconstruction": "relative", "random_state": 0}
    online = OnlineCLMSegmenter(fit.model, window=100, **params).replay(X)
    assert len(X) > 3 * 100
    assert np.mean(online == CLMSegmenter(fit.model, **params).fit_predict(X)) >= 0.98


def test_train_classes_on_recordings_feeds_the_online_node_in_relative_mode(tmp_path):
    """`handflow train-classes RECORDINGS` writes delay models on velocities with their scaling; the
    online node picks the relative reconstruction they were made for, derives the velocities and
    labels the raw stream as the batch does."""
    import subprocess
    import sys

    from handflow.framework.messages import Array
    from handflow.framework.testkit.harness import NodeHarness
    from handflow.plugins.segmenter.models import load_candidates
    from handflow.plugins.segmenter.nodes import OnlineCLMNode

    arrays = {"class_names": np.array(["a", "b", "c"])}
    for k in range(3):
        X, y = _synthetic_recordings(k)
        arrays[f"X_r{k}"], arrays[f"y_r{k}"] = 5.0 * X + 3.0, y  # raw units: the models carry the z-scoring
    np.savez(tmp_path / "rec.npz", **arrays)
    cmd = [sys.executable, "-m", "handflow.framework.cli", "train-classes", str(tmp_path / "rec.npz")]
    done = subprocess.run(
        [*cmd, "--out", str(tmp_path / "m"), "--delay", "4", "--steps", "60", "--derived", "velocities"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    bad = subprocess.run([*cmd, "--out", str(tmp_path / "x"), "--classes", "a,zz"], capture_output=True, text=True)
    assert bad.returncode == 2 and "--classes names classes ['zz']" in bad.stderr

    models = load_candidates(tmp_path / "m")
    assert models.delay == DelayEmbedding(4) and models.reconstruction == "relative"
    assert models.derived == Derived("velocities") and models.n_channels == 2
    X, y = _synthetic_recordings(7)
    X = 5.0 * X + 3.0
    params = {"models": str(tmp_path / "m"), "window": 400, "history": 10, "background_factor": 0.0, "block": 0}
    h = NodeHarness(OnlineCLMNode, params).setup()
    assert h.node.segmenter.reconstruction == "relative"
    for i, x in enumerate(X):
        h.send("array", Array(data=x), stamp_ns=i * 10_000_000)
    on_arrival = np.array(
        [models.classes.index(m.label) if m.label in models.classes else -1 for m in h.published["labels"]]
    )
    assert len(on_arrival) == len(X) and np.mean(on_arrival == y) > 0.7
    batch = CLMSegmenter(models, history=10, background_factor=0.0, reconstruction="relative", random_state=0)
    assert np.mean(batch.fit_predict(X) == y) > 0.8


def test_models_on_velocities_derive_them_from_a_raw_stream_as_from_the_recording(tmp_path):
    from handflow.plugins.segmenter.models import fit_recording_models, load_candidates, save_class_models

    X, y = _synthetic_recordings(0)
    segs = {str(c): [X[y == c]] for c in (0, 1, 2)}
    models = fit_recording_models(segs, delay=4, n_steps=40, derived="velocities")
    assert models.derived.active and models.stateful and models.n_channels == X.shape[1]
    batch = models.project(X)
    stream = models.stream()
    streamed = np.vstack([stream.project(x).errors for x in X])
    np.testing.assert_allclose(streamed, batch.errors, rtol=1e-6, atol=1e-12)  # rounding (docs/segmentation.md)
    weights = np.vstack([stream.intensity_weights(x) for x in X])
    np.testing.assert_allclose(weights, models.intensity_weights(X))
    assert np.mean(np.argmin(batch.errors, axis=1) == y) > 0.8
    save_class_models(models, tmp_path)
    assert load_candidates(tmp_path).derived == Derived("velocities")
    np.testing.assert_allclose(load_candidates(tmp_path).project(X).errors, batch.errors)


@given(n=st.integers(1, 20), d=st.integers(1, 3), seed=st.integers(0, 9))
@settings(max_examples=30, deadline=None)
def test_streamed_velocities_equal_the_recording_derived_at_once(n, d, seed):
    X = np.random.default_rng(seed).normal(size=(n, d))
    stream = Derived("velocities").stream()
    np.testing.assert_array_equal(np.array([stream.push(x) for x in X]), Derived("velocities").transform(X))
    assert len(Derived("velocities").complete(X)) == max(n - 1, 1)


@pytest.mark.parametrize("bad", ["accelerations", 3, None, ["velocities"]])
def test_a_model_file_with_unknown_derived_features_is_refused(bad):
    with pytest.raises(ValueError, match="retrain the models"):
        Derived.from_provenance({"derived": bad})


@pytest.mark.slow
def test_open_set_selection_of_the_ukr_clm_rejects_a_held_out_class(tmp_path):
    """The calibrated null model: class c is never trained on, most of its frames are rejected,
    the known classes are kept (pseudo-unknowns of the inner folds chose the operating point)."""
    _, res = held_out_class_evaluation(tmp_path, "ukr_clm", recordings=3)  # the fewest: a third of five's fits
    assert res["unknown_rejection"] > 0.5 and res["known_accuracy"] > 0.5
    assert all(f["selected"]["reject"] > 0 for f in res["folds"])


@pytest.fixture(scope="module")
def relative_model_dir(tmp_path_factory):
    from handflow.plugins.segmenter.models import fit_recording_models, save_class_models

    X, y = _synthetic_recordings(0)
    cands = fit_recording_models({c: [X[y == i]] for i, c in enumerate("abc")}, delay=4, n_steps=40, scaling="standard")
    return save_class_models(cands, tmp_path_factory.mktemp("relative"))


@settings(max_examples=60, deadline=None)
@given(
    values=st.lists(
        st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=0, max_size=4),
        min_size=1,
        max_size=8,
    )
)
def test_no_observation_crashes_the_node_with_delay_models(relative_model_dir, values):
    """Any observation — wrong size, NaN/inf, ±1e308 — is labelled or dropped with a reason; the
    delay buffer never takes a bad one."""
    from handflow.framework.messages import Array
    from handflow.framework.testkit.harness import NodeHarness
    from handflow.plugins.segmenter.nodes import OnlineCLMNode

    h = NodeHarness(OnlineCLMNode, {"models": str(relative_model_dir), "window": 20, "background_factor": 0.25})
    h.setup()
    for v in values:
        h.send("array", Array(data=v))
    assert len(h.published["labels"]) + len(h.dropped) == len(values)
