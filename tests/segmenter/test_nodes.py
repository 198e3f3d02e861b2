import numpy as np
import pytest
import sklearn.base

from handflow.framework.messages import Array, JointState
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.segmenter import save_class_models
from handflow.plugins.segmenter.base import lagged
from handflow.plugins.segmenter.datasets import Recording, basicmotions_continuous, load_recordings, segments
from handflow.plugins.segmenter.models import ModelsMissingError, fit_recording_models
from handflow.plugins.segmenter.nodes import UNKNOWN, OnlineCLMNode, UKROnlyNode
from tests.segmenter.conftest import SHARED
from tests.segmenter.datasets.test_recordings import _synthetic_recordings


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory, ukr_models):
    return save_class_models(ukr_models, tmp_path_factory.mktemp("models"))


def test_online_clm_node_labels_a_stream(model_dir, two_letters):
    Y, truth = two_letters
    h = NodeHarness(OnlineCLMNode, {"models": str(model_dir), "window": 200, "history": 10}).setup()
    for i, y in enumerate(Y):
        h.send("array", Array(data=y), stamp_ns=i * 10_000_000)
    labels = h.published["labels"]
    assert len(labels) == len(Y)
    assert labels[5].classes == ["A", "B", "C", "D"] and labels[5].scores.size == 4
    assert labels[-1].label == "B" and labels[-1].index == len(Y) - 1
    assert labels[-1].header.stamp_ns == (len(Y) - 1) * 10_000_000
    kinds = {e.kind for e in h.published["events"]}
    assert {"start", "end"} <= kinds
    assert any(e.kind == "start" and e.label == "B" for e in h.published["events"])


def test_online_clm_node_labels_as_a_fresh_segmenter_after_its_warm_up(model_dir, two_letters):
    """The warm-up in setup (one update, then reset) leaves no trace: window and generator start afresh."""
    Y, _ = two_letters
    h = NodeHarness(OnlineCLMNode, {"models": str(model_dir), "window": 100, "history": 10, "seed": 3}).setup()
    fresh = sklearn.base.clone(h.node.segmenter)
    for i, y in enumerate(Y):
        h.send("array", Array(data=y), stamp_ns=i)
        up = fresh.update(y)
        label = h.published["labels"][-1]
        assert (label.index, label.label) == (up.index, h.node.name(up.label))
        np.testing.assert_array_equal(label.scores, up.scores)


def test_online_clm_node_revisions_are_confirmed_and_move_boundaries(model_dir, two_letters):
    Y, _ = two_letters
    params = {"models": str(model_dir), "window": 200, "history": 10, "confirm": 3, "error_scale": 1.0}
    h = NodeHarness(OnlineCLMNode, params).setup()
    assert h.node.segmenter.confirm == 3
    for i, y in enumerate(Y):
        h.send("array", Array(data=y), stamp_ns=i * 10_000_000)
    events = h.published["events"]
    for k, e in enumerate(events):
        if e.kind == "revision":
            assert e.previous_label and e.previous_label != e.label
            # the moved boundaries follow the revision in the same batch
            assert events[k + 1].kind in ("start", "end")


def test_online_clm_node_rejects_a_reversed_letter_with_min_progress(model_dir, synthetic):
    a = next(t.data for t in synthetic.test if t.label == "A")
    params = {"models": str(model_dir), "history": 10, "background_factor": 0.5, "min_progress": 0.3, "block": 50}
    h = NodeHarness(OnlineCLMNode, params).setup()
    assert h.node.segmenter.min_progress == 0.3
    labels = [""] * len(a)
    for i, y in enumerate(a[::-1]):
        h.send("array", Array(data=y), stamp_ns=i * 10_000_000)
        labels[i] = h.published["labels"][-1].label
    h.node.publish_events(h.node.segmenter.finish(), stamp=0)
    for e in h.published["events"]:
        if e.kind == "revision":
            labels[e.start_index : e.end_index + 1] = [e.label] * (e.end_index - e.start_index + 1)
    assert sum(label == UNKNOWN for label in labels) > 0.9 * len(a)
    with pytest.raises(Exception, match="min_progress needs source 'ukr'"):
        NodeHarness(OnlineCLMNode, {"source": "dtw", "scorer": "s.npz", "min_progress": 0.3})
    with pytest.raises(Exception, match="max_fit_ratio needs source 'ukr'"):
        NodeHarness(OnlineCLMNode, {"source": "dtw", "scorer": "s.npz", "max_fit_ratio": 2.0})
    with pytest.raises(Exception, match="max_fit_ratio"):
        NodeHarness(OnlineCLMNode, {"models": str(model_dir), "max_fit_ratio": 0.5})
    h = NodeHarness(OnlineCLMNode, dict(params, max_fit_ratio=2.0)).setup()
    assert h.node.segmenter.max_fit_ratio == 2.0


def test_ukr_only_node_takes_joint_states_in_model_order(model_dir, two_letters):
    Y, _ = two_letters
    h = NodeHarness(UKROnlyNode, {"models": str(model_dir), "joints": ["x", "y"]}).setup()
    for y in Y[:60]:
        h.send("joints", JointState(names=["y", "x", "z"], positions=[y[1], y[0], 0.0]))
    assert [m.label for m in h.published["labels"][-10:]] == ["A"] * 10
    h.send("joints", JointState(names=["x"], positions=[0.0]))  # lacks 'y': dropped, logged
    assert len(h.published["labels"]) == 60 and len(h.dropped) == 1


@pytest.mark.parametrize("cls", [OnlineCLMNode, UKROnlyNode])
def test_recognisers_compute_on_one_blas_thread_and_restore_the_limit(model_dir, two_letters, cls):
    """Each observation is recognised with BLAS limited to one thread (docs/segmentation.md, "Nodes"),
    and the process's limit is back afterwards (other nodes of the group keep theirs)."""
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas_threads() -> set[int]:
        return {lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"}

    Y, _ = two_letters
    with threadpool_limits(2, user_api="blas"):
        before = blas_threads()
        h = NodeHarness(cls, {"models": str(model_dir)}).setup()
        seen, recognise = [], h.node.recognise
        h.node.recognise = lambda y, stamp: (seen.append(blas_threads()), recognise(y, stamp))
        for i, y in enumerate(Y[:5]):
            h.send("array", Array(data=y), stamp_ns=i)
        assert seen == [{1}] * 5 and len(h.published["labels"]) == 5
        assert blas_threads() == before


def test_missing_models_fail_setup_with_the_training_hint(tmp_path):
    with pytest.raises(ModelsMissingError, match="train-classes"):
        NodeHarness(OnlineCLMNode, {"models": str(tmp_path / "none")}).setup()


def test_unknown_parameter_is_refused():
    with pytest.raises(Exception, match="extra"):
        NodeHarness(OnlineCLMNode, {"models": "m", "windw": 3})


def test_published_messages_survive_the_json_codec(model_dir, two_letters):
    from handflow.framework.messages import decode, encode

    Y, _ = two_letters
    h = NodeHarness(OnlineCLMNode, {"models": str(model_dir)}).setup()
    for y in Y:
        h.send("array", Array(data=y))
    for msgs in h.published.values():
        for m in msgs:
            assert encode(decode(encode(m))) == encode(m)


def _final_labels(h: NodeHarness, n: int) -> np.ndarray:
    """Each index's label as the node last published it: on arrival, then by revisions."""
    final = np.full(n, "", dtype=object)
    for msg in h.published["labels"]:
        final[msg.index] = msg.label
    for ev in h.published["events"]:
        if ev.kind == "revision":
            final[ev.start_index : ev.end_index + 1] = ev.label
    return final


@pytest.mark.skipif(not (SHARED / "basicmotions.npz").exists(), reason="shared BasicMotions data absent")
def test_online_clm_node_with_a_lag_publishes_the_labels_shifted_by_it(tmp_path):
    """A real recording (BasicMotions made continuous) replayed through the node: with ``lag`` L the
    label of observation t is the one the node without a lag gives observation t + L."""
    np.savez(tmp_path / "bm.npz", **basicmotions_continuous(SHARED / "basicmotions.npz"))
    data = load_recordings(tmp_path / "bm.npz")
    segs = segments(data.recordings[:2], list(range(len(data.class_names))))
    by_class = {data.class_names[c]: s for c, s in segs.items()}
    models = save_class_models(fit_recording_models(by_class, delay=8, n_steps=30, scaling="standard"), tmp_path / "m")
    X = data.recordings[2].X[:300]
    published = {}
    for lag in (0, 4):
        params = {"models": str(models), "window": 60, "history": 10, "background_factor": 0.25, "lag": lag}
        h = NodeHarness(OnlineCLMNode, params).setup()
        for i, y in enumerate(X):
            h.send("array", Array(data=y), stamp_ns=i)
        assert [m.index for m in h.published["labels"]] == list(range(len(X) - lag))
        assert h.published["labels"][0].header.stamp_ns == lag  # published when the later window is complete
        published[lag] = _final_labels(h, len(X) - lag)
    assert len(set(published[0])) > 1  # the recording changes class: there are boundaries to move
    assert np.array_equal(published[4], lagged(published[0], 4)[: len(X) - 4])


def test_online_clm_node_adapts_its_models_to_the_session_of_an_enrolment_recording(tmp_path):
    """A session recorded elsewhere (every channel scaled and shifted): with ``enroll`` the node's
    models are refitted with its first segment per class and — ``align`` — the stream is aligned by
    the session's enrolment, so the models explain the session's frames far better."""
    train = {"class_names": np.array(["a", "b", "c"])}
    for k in range(2):
        train[f"X_r{k}"], train[f"y_r{k}"] = _synthetic_recordings(k)
    np.savez(tmp_path / "train.npz", **train)
    X, y = _synthetic_recordings(5)
    X = 2.0 * X + 1.5
    np.savez(tmp_path / "session.npz", class_names=np.array(["a", "b", "c", "d"]), X_s=X, y_s=y)
    by_class = dict(zip("abc", segments(load_recordings(tmp_path / "train.npz").recordings, [0, 1, 2]).values()))
    models = fit_recording_models(by_class, delay=4, n_steps=20, scaling="standard")
    provenance = {"dataset": str(tmp_path / "train.npz"), "steps": 20, "background_factor": 0.5}
    params = {"models": str(save_class_models(models, tmp_path / "m", provenance=provenance)), "window": 60}
    a = segments([Recording("s", X, y)], [0])[0][-1]  # the session's last 'a' (not enrolled)

    def own_error(extra: dict) -> float:
        node = NodeHarness(OnlineCLMNode, dict(params, **extra)).setup().node
        assert node.segmenter.classes_ == ["a", "b", "c"] and node.segmenter.background_factor == 0.5
        seen = a if node.running is None else node.running(a)
        return float(np.median(node.segmenter.candidates.project(seen).errors[:, 0]))

    plain = own_error({})
    session = str(tmp_path / "session.npz")
    assert own_error({"enroll": session}) < 0.3 * plain
    assert own_error({"enroll": session, "enroll_adaptation": "refit"}) < plain
    with pytest.raises(ValueError, match="lower enroll_segments"):
        own_error({"enroll": session, "enroll_segments": 3})
    with pytest.raises(ValueError, match="enroll needs source 'ukr'"):
        NodeHarness(OnlineCLMNode, {"source": "dtw", "scorer": "s.npz", "enroll": "e.npz"})


def _labels_with_a_change_halfway(model_dir, Y, cls, params, key, value):
    h = NodeHarness(cls, {"models": str(model_dir), **params}).setup()
    for i, y in enumerate(Y):
        if i == len(Y) // 2 and key is not None:
            h.set_param(key, value)
        h.send("array", Array(data=y), stamp_ns=i)
    return [m.label for m in h.published["labels"]]


@pytest.mark.parametrize(
    ("cls", "params", "key", "value"),
    [(OnlineCLMNode, {"window": 100, "history": 10}, "background_factor", 50.0), (UKROnlyNode, {}, "threshold", 2.0)],
)
def test_a_live_rejection_level_rejects_from_the_next_observation_on(model_dir, two_letters, cls, params, key, value):
    """docs/tuning.md: the stream is kept (same labels up to the change), the new level rejects after it."""
    Y, _ = two_letters
    half = len(Y) // 2
    unchanged = _labels_with_a_change_halfway(model_dir, Y, cls, params, None, None)
    changed = _labels_with_a_change_halfway(model_dir, Y, cls, params, key, value)
    assert changed[:half] == unchanged[:half]
    assert changed[half:].count(UNKNOWN) > unchanged[half:].count(UNKNOWN) + half // 2


def test_a_start_only_or_invalid_segmenter_parameter_is_refused_while_running(model_dir):
    from handflow.framework.runtime.live_params import ParamRefused

    h = NodeHarness(OnlineCLMNode, {"models": str(model_dir), "window": 100}).setup()
    with pytest.raises(ParamRefused, match="window needs a restart"):
        h.set_param("window", 50)
    with pytest.raises(ParamRefused, match="greater than or equal to 0"):
        h.set_param("background_factor", -1)
    assert h.node.params.window == 100 and h.node.params.background_factor is None
