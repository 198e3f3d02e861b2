"""Frame scorers saved without pickle, the online CLM over their evidence, the node and fit-scorer."""

import json
import math
import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from handflow.framework.messages import Array
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.segmenter.cli import register_fit_scorer
from handflow.plugins.segmenter.datasets import load_recordings, segments
from handflow.plugins.segmenter.nodes import OnlineCLMNode
from handflow.plugins.segmenter.online import OnlineScoreCLMSegmenter, batch_labels
from handflow.plugins.segmenter.scorers import FORMAT_VERSION, DTWScorer, MiniRocketScorer, ScorerFileError, load_scorer
from tests.conftest import run_command
from tests.garbage import damaged_file
from tests.segmenter.datasets.test_recordings import _indistinguishable_recordings

DEMO = Path(__file__).resolve().parents[3] / "recordings" / "segmenter_demo"
FUZZ = settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def demo():
    """The shipped synthetic continuous recordings (3 classes, 3 channels): training segments, test recording."""
    data = load_recordings(DEMO)
    segs = segments(data.recordings[1:], list(range(len(data.class_names))))
    return {data.class_names[c]: s for c, s in segs.items()}, data.recordings[0]


@pytest.fixture(scope="module")
def minirocket(demo, tmp_path_factory):
    pytest.importorskip("aeon")
    scorer = MiniRocketScorer(window=16, n_kernels=840, random_state=0).fit(demo[0])
    return scorer, scorer.save(tmp_path_factory.mktemp("scorer") / "minirocket.npz")


@pytest.fixture(scope="module")
def dtw(demo, tmp_path_factory):
    scorer = DTWScorer(window=8, thin=4).fit(demo[0])
    return scorer, scorer.save(tmp_path_factory.mktemp("scorer") / "dtw.npz")


@pytest.mark.parametrize("limit, per_segment", [(10_000, 12), (30, 2), (5, 1)])
def test_minirocket_trains_on_fewer_windows_per_segment_beyond_the_limit(demo, monkeypatch, limit, per_segment):
    """Every segment keeps at least one window; beyond ``MAX_TRAINING_WINDOWS`` each keeps fewer."""
    pytest.importorskip("aeon")
    from handflow.plugins.segmenter.scorers import _minirocket

    taken, windows = [], _minirocket.causal_windows

    def counted(X, ends, width):
        taken.append(len(ends))
        return windows(X, ends, width)

    monkeypatch.setattr(_minirocket, "MAX_TRAINING_WINDOWS", limit)
    monkeypatch.setattr(_minirocket, "causal_windows", counted)
    MiniRocketScorer(window=16, n_kernels=84, random_state=0, feature_novelty=False).fit(demo[0])
    assert taken == [per_segment] * sum(map(len, demo[0].values()))  # 18 segments


def test_reloaded_minirocket_scores_exactly_like_the_fitted_one(minirocket, demo):
    scorer, path = minirocket
    X = demo[1].X
    again = load_scorer(path)
    assert isinstance(again, MiniRocketScorer) and again.classes_ == ["circle", "rest", "wave"]
    np.testing.assert_array_equal(again.scores(X), scorer.scores(X))
    np.testing.assert_array_equal(again.scores_and_novelty(X)[1], scorer.scores_and_novelty(X)[1])
    assert again.temperature_ == scorer.temperature_
    assert np.mean(scorer.scores(X).argmax(axis=1) == demo[1].y) > 0.8  # it learned the classes


def test_reloaded_dtw_scores_exactly_like_the_fitted_one(dtw, demo):
    scorer, path = dtw
    X = demo[1].X[:120]
    np.testing.assert_array_equal(load_scorer(path).scores(X), scorer.scores(X))


def test_scores_of_the_last_frame_equal_the_batch_scores(minirocket, demo):
    scorer, _ = minirocket
    X = demo[1].X[:40]
    batch = scorer.scores(X)
    for t in (0, 5, 15, 39):  # within and past the first window
        np.testing.assert_allclose(scorer.scores_last(X[max(0, t - 15) : t + 1]), batch[t], rtol=1e-9, atol=1e-9)


def test_feature_novelty_of_the_last_frame_equals_the_batch(minirocket, demo):
    scorer, _ = minirocket
    X = demo[1].X[:40]
    scores, novelty = scorer.scores_and_novelty(X)
    np.testing.assert_array_equal(scores, scorer.scores(X))
    for t in (0, 15, 39):
        last = scorer.scores_and_novelty_last(X[max(0, t - 15) : t + 1])
        np.testing.assert_allclose(last[0], scores[t], rtol=1e-9, atol=1e-9)
        assert last[1] == pytest.approx(novelty[t], rel=1e-9, abs=1e-9)
    assert DTWScorer(window=8).fit(demo[0]).scores_and_novelty(X)[1] is None  # no features, no feature novelty


def test_fixed_temperature_maps_scores_to_evidence(minirocket):
    scorer, _ = minirocket
    e = scorer.evidence(np.array([0.0, scorer.temperature_, -1.0]))
    assert e.shape == (1, 3) and math.isclose(e.sum(), 1.0)
    assert math.isclose(e[0, 1] / e[0, 0], math.e)


def _rewrite(path: Path, out: Path, edit) -> Path:
    with np.load(path) as d:
        arrays = {k: d[k] for k in d.files}
    meta = json.loads(str(arrays.pop("metadata")))
    edit(meta, arrays)
    np.savez(out, metadata=np.array(json.dumps(meta)), **arrays)
    return out


@pytest.mark.parametrize("version", [FORMAT_VERSION - 1, FORMAT_VERSION + 1])
def test_file_of_another_version_is_refused_with_what_to_do(dtw, tmp_path, version):
    bad = _rewrite(dtw[1], tmp_path / "other.npz", lambda m, a: m.update(version=version))
    with pytest.raises(ScorerFileError, match=rf"version {version}.*reads version {FORMAT_VERSION}.*fit-scorer"):
        load_scorer(bad)


def test_edited_array_is_refused(dtw, tmp_path):
    def edit(meta, arrays):
        arrays["refs"] = arrays["refs"] + 1.0

    with pytest.raises(ScorerFileError, match="'refs' is missing or changed"):
        load_scorer(_rewrite(dtw[1], tmp_path / "edited.npz", edit))


def test_missing_and_foreign_files_are_refused(tmp_path):
    with pytest.raises(ScorerFileError, match="no such scorer file"):
        load_scorer(tmp_path / "none.npz")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(ScorerFileError, match="no scorer metadata"):
        load_scorer(tmp_path / "other.npz")
    (tmp_path / "text.npz").write_text("hello")
    with pytest.raises(ScorerFileError, match="not a scorer file: that is an .npz archive"):
        load_scorer(tmp_path / "text.npz")
    # an .npy header cut inside its dictionary: numpy's reader raises tokenize.TokenError
    header = b"{'descr': '<f8', 'fortran_order': False, 'shape': (3,"
    header += b" " * (53 - len(header)) + b"\n"
    with zipfile.ZipFile(tmp_path / "header.npz", "w") as z:
        z.writestr("metadata.npy", b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header + bytes(24))
    with pytest.raises(ScorerFileError, match="not a readable scorer file"):
        load_scorer(tmp_path / "header.npz")


@FUZZ
@given(data=st.data())
def test_mutated_scorer_files_load_identically_or_fail_clearly(minirocket, dtw, demo, tmp_path, data):
    """Truncated or byte-edited files: a ScorerFileError, or (bytes nobody reads) the same scores."""
    scorer, path = data.draw(st.sampled_from([minirocket, dtw]))
    bad = tmp_path / "mutated.npz"
    bad.write_bytes(damaged_file(data.draw, path.read_bytes()))
    try:
        again = load_scorer(bad)
    except ScorerFileError:
        return
    X = demo[1].X[:30]
    np.testing.assert_array_equal(again.scores(X), scorer.scores(X))


JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=5),
    lambda kids: st.lists(kids, max_size=3) | st.dictionaries(st.text(max_size=5), kids, max_size=3),
    max_leaves=8,
)


@FUZZ
@given(
    key=st.sampled_from(
        "kind params classes n_features_in temperature sha256 version null_score null_calibration".split()
    ),
    value=JSON,
)
def test_garbled_metadata_fails_clearly(minirocket, tmp_path, key, value):
    bad = _rewrite(minirocket[1], tmp_path / "meta.npz", lambda m, a: m.update({key: value}))
    try:
        load_scorer(bad)
    except ScorerFileError:
        pass


def test_online_segmenter_over_scores_agrees_with_the_batch_clm(minirocket, demo):
    scorer, _ = minirocket
    X, y = demo[1].X, demo[1].y
    online = OnlineScoreCLMSegmenter(scorer, window=150, history=10, background_factor=0.0, random_state=0)
    labels = online.replay(X)
    assert online.classes_ == ["circle", "rest", "wave"]
    batch = batch_labels(scorer, X, history=10, background_factor=0.0, random_state=0)
    assert np.mean(labels == batch) > 0.9
    assert np.mean(labels == y) > 0.8
    up = online.update(X[0])  # the stream goes on sample by sample
    assert up.index == len(X) and up.scores.shape == (3,)


def test_node_segments_with_a_minirocket_source(minirocket, demo):
    _, path = minirocket
    X = demo[1].X
    h = NodeHarness(
        OnlineCLMNode, {"source": "minirocket", "scorer": str(path), "window": 100, "background_factor": 0.25}
    ).setup()
    for i, x in enumerate(X[:200]):
        h.send("array", Array(data=x), stamp_ns=i * 10_000_000)
    labels = h.published["labels"]
    assert len(labels) == 200 and labels[0].classes == ["circle", "rest", "wave"]
    names = np.array(["circle", "rest", "wave"])
    assert np.mean(np.array([m.label for m in labels]) == names[demo[1].y[:200]]) > 0.8
    assert {"start", "end"} <= {e.kind for e in h.published["events"]}
    h.send("array", Array(data=X[0, :2]))  # wrong dimension: dropped, logged
    h.send("array", Array(data=[np.nan, 0.0, 0.0]))  # NaN: dropped, logged
    assert len(h.published["labels"]) == 200 and len(h.dropped) == 2


def test_node_source_needs_its_file_and_the_matching_kind(dtw):
    with pytest.raises(Exception, match="needs 'scorer'"):
        NodeHarness(OnlineCLMNode, {"source": "minirocket"})
    with pytest.raises(Exception, match="needs 'models'"):
        NodeHarness(OnlineCLMNode, {})
    with pytest.raises(ScorerFileError, match="set source: dtw"):
        NodeHarness(OnlineCLMNode, {"source": "minirocket", "scorer": str(dtw[1])}).setup()


def test_fit_scorer_command_writes_a_loadable_scorer(tmp_path, capsys):
    out = tmp_path / "dtw.npz"
    assert (
        run_command(
            register_fit_scorer,
            [str(DEMO), "--source", "dtw", "--window", "8", "--known", "circle,wave", "--out", str(out)],
        )
        == 0
    )
    assert "2 classes" in capsys.readouterr().out
    assert load_scorer(out).classes_ == ["circle", "wave"]
    assert zipfile.is_zipfile(out)
    assert run_command(register_fit_scorer, [str(DEMO), "--source", "dtw", "--known", "jump", "--out", str(out)]) == 2
    assert "lacks" in capsys.readouterr().err


@FUZZ
@given(values=st.lists(st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5), min_size=1, max_size=6))
def test_no_observation_crashes_the_node_with_a_scorer_source(dtw, values):
    h = NodeHarness(OnlineCLMNode, {"source": "dtw", "scorer": str(dtw[1]), "window": 20, "background_factor": 0.5})
    h.setup()
    for v in values:
        h.send("array", Array(data=v))
    assert len(h.published["labels"]) + len(h.dropped) == len(values)


@pytest.fixture(scope="module")
def novelty_setup(demo, tmp_path_factory):
    """A DTW scorer and class manifolds (delay 4) of circle and wave only: 'rest' is unknown."""
    from handflow.plugins.segmenter.models import fit_recording_models, save_class_models

    known = {c: demo[0][c] for c in ("circle", "wave")}
    scorer = DTWScorer(window=8, thin=4).fit(known)
    models = fit_recording_models(known, delay=4, n_steps=60, random_state=0)
    folder = save_class_models(models, tmp_path_factory.mktemp("novelty"))
    return scorer, scorer.save(tmp_path_factory.mktemp("scorer") / "dtw.npz"), models, folder


def test_novelty_models_reject_unknown_motion_online_as_in_the_batch(novelty_setup, demo):
    scorer, _, models, _ = novelty_setup
    X, y = demo[1].X, demo[1].y
    rest = y == 1  # class index 1 of circle / rest / wave: never trained on
    params = dict(history=10, background_factor=0.25, random_state=0)
    plain = batch_labels(scorer, X, **params)
    batch = batch_labels(scorer, X, novelty_models=models, novelty=0.5, **params)
    assert np.mean(plain[rest] == -1) < 0.5 < np.mean(batch[rest] == -1)  # the classifier alone keeps 'rest'
    names = np.array(["circle", "rest", "wave"])
    known = ~rest
    assert np.mean(names[y[known]] == np.array(scorer.classes_ + ["-"])[batch[known]]) > 0.8
    online = OnlineScoreCLMSegmenter(scorer, novelty_models=models, novelty=0.5, window=150, **params)
    assert np.mean(online.replay(X) == batch) > 0.9


def test_node_takes_novelty_models_with_a_scorer_source(novelty_setup, demo):
    _, path, _, folder = novelty_setup
    h = NodeHarness(
        OnlineCLMNode,
        {
            "source": "dtw",
            "scorer": str(path),
            "novelty_models": str(folder),
            "novelty": 0.5,
            "window": 100,
            "background_factor": 0.25,
        },
    ).setup()
    X, y = demo[1].X, demo[1].y
    for i, x in enumerate(X[:300]):
        h.send("array", Array(data=x), stamp_ns=i * 10_000_000)
    labels = np.array([m.label for m in h.published["labels"]])
    assert len(labels) == 300 and np.mean(labels[y[:300] == 1] == "unknown") > 0.5
    with pytest.raises(Exception, match="novelty_models needs source"):
        NodeHarness(OnlineCLMNode, {"models": str(folder), "novelty_models": str(folder)})


@pytest.fixture(scope="module")
def rocket_without_rest(demo):
    """A MiniRocket scorer of circle and wave only: 'rest' is unknown."""
    pytest.importorskip("aeon")
    return MiniRocketScorer(window=16, n_kernels=840, random_state=0).fit({c: demo[0][c] for c in ("circle", "wave")})


def test_feature_novelty_rejects_unknown_motion_online_as_in_the_batch(rocket_without_rest, demo):
    scorer = rocket_without_rest
    X, y = demo[1].X, demo[1].y
    rest = y == 1
    params = dict(history=10, background_factor=0.25, random_state=0)
    plain = batch_labels(scorer, X, **params)
    batch = batch_labels(scorer, X, distance_z=2.0, **params)
    assert np.mean(plain[rest] == -1) < 0.5 < np.mean(batch[rest] == -1)  # the classifier alone keeps 'rest'
    names = np.array(["circle", "rest", "wave"])
    # most known frames kept (windows across a change of motion lie far from every training window)
    assert np.mean(names[y[~rest]] == np.array(scorer.classes_ + ["-"])[batch[~rest]]) > 0.75
    online = OnlineScoreCLMSegmenter(scorer, distance_z=2.0, window=150, **params)
    assert np.mean(online.replay(X) == batch) > 0.9


def test_distance_z_needs_a_scorer_with_features(dtw, minirocket, demo, tmp_path):
    with pytest.raises(ValueError, match="distance_z needs a scorer with features"):
        OnlineScoreCLMSegmenter(dtw[0], distance_z=2.0)
    plain = MiniRocketScorer(window=16, n_kernels=840, random_state=0, feature_novelty=False).fit(demo[0])
    assert plain.novelty_ is None and not plain.has_features  # the scores alone: the novelty is not fitted
    np.testing.assert_array_equal(plain.scores(demo[1].X), minirocket[0].scores(demo[1].X))
    with pytest.raises(ValueError, match="distance_z needs a scorer with features"):
        OnlineScoreCLMSegmenter(plain, distance_z=2.0)
    with pytest.raises(ValueError, match="fit it with feature_novelty=True"):
        plain.save(tmp_path / "plain.npz")
    with pytest.raises(Exception, match="distance_z needs source minirocket"):
        NodeHarness(OnlineCLMNode, {"source": "dtw", "scorer": str(dtw[1]), "distance_z": 2.0})


def test_novelty_models_with_another_channel_count_are_refused_at_start(novelty_setup, demo, tmp_path):
    from handflow.plugins.segmenter.models import fit_recording_models, save_class_models

    _, path, _, _ = novelty_setup
    two = {c: [s[:, :2] for s in demo[0][c]] for c in ("circle", "wave")}
    models = fit_recording_models(two, delay=4, n_steps=20, random_state=0)
    folder = save_class_models(models, tmp_path)
    with pytest.raises(ValueError, match="trained on 2 channels, the scorer on 3"):
        NodeHarness(OnlineCLMNode, {"source": "dtw", "scorer": str(path), "novelty_models": str(folder)}).setup()


def test_online_segmenter_with_a_null_class_agrees_with_the_batch_clm(dtw, demo):
    """The null class rejects on the scorer's scale online as in the batch (docs/segmentation.md)."""
    scorer, _ = dtw
    X = demo[1].X
    threshold = float(np.quantile(scorer.scores(X).max(axis=1), 0.2))
    params = dict(history=10, random_state=0)
    online = OnlineScoreCLMSegmenter(scorer, window=150, null_score=threshold, **params)
    assert online.get_params()["null_score"] == threshold and online.reconstruction == "relative"
    labels = online.replay(X)
    assert np.mean(labels == batch_labels(scorer, X, null_score=threshold, **params)) > 0.9
    kept = labels >= 0  # the frames the scorer is least sure of are rejected, the others mostly right
    assert 0.05 < np.mean(~kept) < 0.5 and np.mean(labels[kept] == demo[1].y[kept]) > 0.9
    up = online.update(X[0])  # the stream goes on: the class layers' activities, the null class's left out
    assert up.scores.shape == (3,)
    for null, rejected in ((np.inf, 1.0), (-np.inf, 0.0)):
        everything = OnlineScoreCLMSegmenter(scorer, window=150, null_score=null, **params).replay(X[:200])
        assert np.mean(everything == -1) == rejected
        assert np.mean(batch_labels(scorer, X[:200], null_score=null, **params) == -1) == rejected


def test_set_params_switches_the_null_class_as_the_constructor_does(dtw, demo):
    scorer, _ = dtw
    X = demo[1].X[:200]
    built = OnlineScoreCLMSegmenter(scorer, window=150, history=10, random_state=0)
    assert built.reconstruction == "absolute"
    built.set_params(null_score=np.inf)
    assert built.reconstruction == "relative" and np.all(built.replay(X) == -1)
    fresh = OnlineScoreCLMSegmenter(scorer, window=150, history=10, random_state=0, null_score=np.inf)
    mine, theirs = built.get_params(deep=False), fresh.get_params(deep=False)
    assert mine.pop("solver").get_params() == theirs.pop("solver").get_params() and mine == theirs
    built.set_params(null_score=None)
    assert built.reconstruction == "absolute" and built.null_score is None
    with pytest.raises(ValueError, match="invalid parameters"):
        built.set_params(nul_score=0.0)


def test_a_null_class_is_one_way_to_reject(dtw, rocket_without_rest, novelty_setup):
    with pytest.raises(ValueError, match="choose one"):
        OnlineScoreCLMSegmenter(dtw[0], novelty_models=novelty_setup[2], null_score=0.0)
    with pytest.raises(ValueError, match="choose one"):
        batch_labels(rocket_without_rest, np.zeros((5, 3)), distance_z=2.0, null_score=0.0)
    with pytest.raises(ValueError, match="reconstruction 'absolute' does not apply"):
        OnlineScoreCLMSegmenter(dtw[0], null_score=0.0, reconstruction="absolute")
    with pytest.raises(ValueError, match="reconstruction 'relative' does not apply"):
        OnlineScoreCLMSegmenter(dtw[0], reconstruction="relative")


def test_fit_scorer_calibrates_the_null_class_for_the_node(tmp_path, capsys):
    out = tmp_path / "dtw.npz"
    assert run_command(register_fit_scorer, [str(DEMO), "--source", "dtw", "--window", "8", "--out", str(out)]) == 0
    scorer = load_scorer(out)
    assert np.isfinite(scorer.null_score_) and scorer.null_calibration_["rejection"] == "calibrated"
    assert scorer.null_calibration_["validation_objective"] > 0.55
    assert f"null class: score {scorer.null_score_:g} on the scorer's scale" in capsys.readouterr().err
    node = NodeHarness(OnlineCLMNode, {"source": "dtw", "scorer": str(out), "window": 50}).setup().node.segmenter
    assert node.null_score == scorer.null_score_ and node.reconstruction == "relative"
    given = NodeHarness(OnlineCLMNode, {"source": "dtw", "scorer": str(out), "null_score": -1.0}).setup()
    assert given.node.segmenter.null_score == -1.0
    factor = NodeHarness(OnlineCLMNode, {"source": "dtw", "scorer": str(out), "background_factor": 0.5}).setup()
    assert factor.node.segmenter.null_score is None and factor.node.segmenter.background_factor == 0.5
    assert factor.node.segmenter.reconstruction == "absolute"
    with pytest.raises(Exception, match="choose one"):
        NodeHarness(OnlineCLMNode, {"source": "dtw", "scorer": str(out), "null_score": 0.0, "background_factor": 1})
    old = _rewrite(out, tmp_path / "old.npz", lambda m, a: [m.pop("null_score"), m.pop("null_calibration")])
    assert load_scorer(old).null_score_ is None  # a file from before: the node rejects with the background factor
    plain = NodeHarness(OnlineCLMNode, {"source": "dtw", "scorer": str(old)}).setup().node.segmenter
    assert plain.null_score is None and plain.background_factor == 1.0
    bad = _rewrite(out, tmp_path / "bad.npz", lambda m, a: m.update(null_score="high"))
    with pytest.raises(ScorerFileError, match="garbles null_score.*fit-scorer"):
        load_scorer(bad)


def test_fit_scorer_says_when_the_null_class_cannot_be_calibrated(tmp_path, capsys):
    data = _indistinguishable_recordings(tmp_path)  # three 'classes' of one and the same noise
    out = tmp_path / "dtw.npz"
    assert run_command(register_fit_scorer, [data.source, "--source", "dtw", "--window", "4", "--out", str(out)]) == 0
    assert "null class: rejection cannot be calibrated on this data" in capsys.readouterr().err
    scorer = load_scorer(out)  # -inf: written and read back as JSON's -Infinity
    assert scorer.null_score_ == -np.inf and scorer.null_calibration_["rejection"] == "off"
    two = tmp_path / "two"
    two.mkdir()
    for rec in sorted(DEMO.glob("*.csv"))[:2]:
        (two / rec.name).write_text(rec.read_text())
    assert run_command(register_fit_scorer, [str(two), "--source", "dtw", "--window", "8", "--out", str(out)]) == 0
    assert "null class not calibrated (leave-one-recording-out needs at least 3 recordings" in capsys.readouterr().err
    assert load_scorer(out).null_score_ is None
