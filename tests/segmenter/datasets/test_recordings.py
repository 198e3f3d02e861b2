"""Continuous recordings: loaders with clear errors, open-set metrics and the rejection calibration."""

from __future__ import annotations

import importlib.util
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from handflow.plugins.segmenter.base import runs
from handflow.plugins.segmenter.cli import format_stream_table
from handflow.plugins.segmenter.datasets import (
    DatasetError,
    basicmotions_continuous,
    is_continuous,
    load_recordings,
    segments,
)
from handflow.plugins.segmenter.evaluation import (
    REGISTRY,
    DTWMethod,
    Fitted,
    NoveltyCLMMethod,
    RecordingsEvaluator,
    calibrate,
    frame_metrics,
    segment_f1,
    tradeoff_curve,
)
from handflow.plugins.segmenter.features import derive
from handflow.plugins.segmenter.models import fit_recording_models
from tests.segmenter.conftest import SHARED

CSV = "x,y,label\n0,1,walk\n1,2,walk\n2,3,\n3,4,run\n"


def _write(tmp_path, text, name="r1.csv"):
    (tmp_path / name).write_text(text)
    return tmp_path


def test_csv_folder_loads_labels_and_unlabelled_rows(tmp_path):
    _write(tmp_path, CSV)
    _write(tmp_path, CSV.replace("run", "jump"), "r2.csv")
    assert is_continuous(tmp_path)
    rs = load_recordings(tmp_path)
    assert rs.class_names == ["jump", "run", "walk"]
    assert rs.get("r1").y.tolist() == [2, 2, -1, 1]
    assert rs.columns == ["x", "y"]


@pytest.mark.parametrize(
    "text, needle",
    [
        ("x,y\n0,1\n", "last column must be 'label'"),
        ("x,y,label\n0,nan,walk\n1,2,walk\n", "NaN/inf in row 0"),
        ("x,y,label\n0,1,walk\n1,walk\n", "r1.csv:3: 2 values, the header has 3"),
        ("x,y,label\n0,a,walk\n1,2,walk\n", "non-numeric"),
        ("x,y,label\n", "at least one data row"),
    ],
)
def test_bad_csv_recordings_get_clear_errors(tmp_path, text, needle):
    _write(tmp_path, text)
    with pytest.raises(DatasetError, match=needle.replace("(", r"\(")):
        load_recordings(tmp_path)


def test_npz_recordings_and_their_errors(tmp_path):
    good = {"class_names": np.array(["a", "b"]), "X_r": np.zeros((4, 2)), "y_r": np.array([0, 0, 1, -1])}
    np.savez(tmp_path / "ok.npz", **good, t_r=np.arange(4.0))
    assert is_continuous(tmp_path / "ok.npz")
    assert load_recordings(tmp_path / "ok.npz").get("r").y.tolist() == [0, 0, 1, -1]
    for bad, needle in [
        ({**good, "y_r": np.array([0, 0, 1])}, "one integer label per row"),
        ({**good, "y_r": np.array([0, 0, 5, 1])}, "outside -1"),
        ({"X_r": good["X_r"], "y_r": good["y_r"]}, "class_names"),
        ({**good, "X_r": np.full((4, 2), np.inf)}, "NaN/inf"),
    ]:
        np.savez(tmp_path / "bad.npz", **bad)
        with pytest.raises(DatasetError, match=needle):
            load_recordings(tmp_path / "bad.npz")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=300))
def test_mutated_csv_never_crashes_the_loader(tmp_path, junk):
    text = CSV.encode() + junk
    (tmp_path / "r1.csv").write_bytes(text)
    try:
        rs = load_recordings(tmp_path)
    except (DatasetError, UnicodeDecodeError):
        return
    assert all(np.isfinite(r.X).all() for r in rs.recordings)


def test_segments_are_runs_of_known_labels_only():
    from handflow.plugins.segmenter.datasets import Recording

    rec = Recording("r", np.arange(10.0)[:, None], np.array([0, 0, 0, 1, 1, -1, 0, 0, 2, 2]))
    segs = segments([rec], [0, 2])
    assert [s.ravel().tolist() for s in segs[0]] == [[0, 1, 2], [6, 7]]
    assert [s.ravel().tolist() for s in segs[2]] == [[8, 9]]
    assert 1 not in segs


def test_frame_metrics_follow_their_definitions():
    truth = np.array([0, 0, 1, 1, 2, 2, -1])  # class 2 unknown, last frame unlabelled
    pred = np.array([0, -1, 1, 0, -1, 1, 0])
    m = frame_metrics(truth, pred, known=[0, 1])
    assert m["known_accuracy"] == pytest.approx(2 / 4)
    assert m["unknown_rejection"] == pytest.approx(1 / 2)
    assert m["open_set_accuracy"] == pytest.approx(3 / 6)
    # F1 class 0: tp 1, fp 1, fn 1 → 0.5; class 1: tp 1, fp 1 (the unknown frame), fn 1 → 0.5
    assert m["macro_f1"] == pytest.approx(0.5)
    assert frame_metrics(truth[:4], pred[:4], [0, 1])["unknown_rejection"] is None


def test_runs_are_maximal_and_cover_the_sequence():
    assert runs(np.array([1, 1, -1, 2, 2, 2])) == [(1, 0, 2), (-1, 2, 3), (2, 3, 6)]
    assert runs(np.array([], dtype=int)) == []


def test_segment_f1_matches_same_label_at_iou_half():
    truth = np.array([0] * 10 + [1] * 10 + [2] * 10)  # class 2 unknown → must be a rejected run
    assert segment_f1([(truth, np.where(truth == 2, -1, truth))], known=[0, 1]) == pytest.approx(1.0)
    # class-0 run shifted by 5: IoU 5/15 < 0.5 for class 0; class 1 run 15..20 vs 10..20: IoU 0.5 matches
    pred = np.array([1] * 5 + [0] * 10 + [1] * 5 + [-1] * 10)
    # predicted runs: 1@0-5, 0@5-15, 1@15-20, -1@20-30; matched: 1@15-20 (IoU 0.5), -1 run → 2 of 4 / 3 true
    assert segment_f1([(truth, pred)], known=[0, 1]) == pytest.approx(2 * 2 / (4 + 3))
    flicker = np.where(np.arange(30) % 2, truth, -1)  # frame accuracy 50 %, every run one frame long
    assert segment_f1([(truth, flicker)], known=[0, 1, 2]) == pytest.approx(0.0)


def test_segment_f1_pools_recordings_and_ignores_unlabelled_frames():
    truth = np.array([-1, -1, 0, 0, 0, 0])
    pred = np.array([1, 1, 0, 0, 0, 0])  # the class-1 run lies on unlabelled frames only
    assert segment_f1([(truth, pred)], known=[0]) == pytest.approx(1.0)
    other = (np.array([0, 0]), np.array([1, 1]))
    assert segment_f1([(truth, pred), other], known=[0, 1]) == pytest.approx(2 * 1 / (2 + 2))
    assert segment_f1([(np.array([-1]), np.array([-1]))], known=[0]) is None


def test_tradeoff_curve_is_closed_and_its_area_trapezoidal():
    rej, acc, auc = tradeoff_curve([0.9, 0.5], [0.2, 0.6])
    assert rej == [0.0, 0.2, 0.6, 1.0] and acc == [0.9, 0.9, 0.5, 0.0]
    assert auc == pytest.approx(0.2 * 0.9 + 0.4 * 0.7 + 0.4 * 0.25)


def test_calibration_picks_the_point_that_keeps_known_and_rejects_pseudo_unknowns():
    value, score = calibrate(lambda t: 1.0 - t / 10, lambda t: min(1.0, t / 2), [0, 1, 2, 3, 10])
    assert value == 2 and score == pytest.approx(0.9)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 1), st.floats(0, 1)), min_size=1, max_size=9))
def test_calibration_shortcuts_find_the_brute_force_optimum(points):
    """Skipping values that cannot win, and stopping at known accuracy 0, never changes the answer
    when known accuracy falls to 0 and stays there (the grids run from keep-all to reject-all)."""
    known = sorted((k for k, _ in points), reverse=True)
    zero = next((i for i, k in enumerate(known) if k == 0.0), len(known))
    known = known[:zero] + [0.0] * (len(known) - zero)
    pseudo = [p for _, p in points]
    asked = []

    def pseudo_at(i):
        asked.append(i)
        return pseudo[i]

    value, score = calibrate(lambda i: known[i], pseudo_at, range(len(points)))
    brute = [0.5 * (k + p) for k, p in zip(known, pseudo)]
    assert score == pytest.approx(max(brute)) and brute[value] == pytest.approx(score)
    assert 0 in asked and all(0.5 * (known[i] + 1.0) > max(brute[:i]) for i in asked if i > 0)


def _synthetic_recordings(seed: int):
    """Three smooth motion classes (distinct sinusoid shapes) concatenated in random order."""
    rng = np.random.default_rng(seed)
    shapes = [
        lambda t: np.c_[np.sin(t), np.cos(t)],
        lambda t: np.c_[np.sin(2 * t), 0.3 * t % 1],
        lambda t: np.c_[-np.abs(np.sin(t)), np.sin(3 * t)],
    ]
    X, y = [], []
    for c in rng.permutation(np.repeat([0, 1, 2], 2)):
        t = np.linspace(0, 2 * np.pi, int(rng.integers(40, 60)))
        X.append(shapes[c](t) + rng.normal(0, 0.02, (len(t), 2)))
        y.append(np.full(len(t), c))
    return np.vstack(X), np.concatenate(y)


def held_out_class_evaluation(tmp_path, method: str, recordings: int = 5) -> tuple[RecordingsEvaluator, dict]:
    """``recordings`` synthetic recordings of classes a, b, c evaluated with c unknown (never trained on)."""
    arrays = {"class_names": np.array(["a", "b", "c"])}
    for k in range(recordings):
        arrays[f"X_r{k}"], arrays[f"y_r{k}"] = _synthetic_recordings(k)
    np.savez(tmp_path / "s.npz", **arrays)
    ev = RecordingsEvaluator(load_recordings(tmp_path / "s.npz"), known=["a", "b"], methods=(method,), quick=True)
    return ev, ev.evaluate()["methods"][method]


def test_open_set_selection_rejects_a_held_out_class(tmp_path):
    ev, res = held_out_class_evaluation(tmp_path, "dtw_1nn")
    assert res["unknown_rejection"] > 0.5  # class c was never seen: most of its frames are rejected
    assert res["known_accuracy"] > 0.5
    assert 0 <= res["tradeoff_auc"] <= 1
    assert 0 < res["segment_f1"] <= 1 and all("segment_f1" in f for f in res["folds"])
    assert "segment_f1" in format_stream_table(ev.evaluate())
    assert DTWMethod().grid(quick=True)


@pytest.mark.skipif(not (SHARED / "basicmotions.npz").exists(), reason="shared BasicMotions data absent")
def test_basicmotions_made_continuous_keeps_every_case(tmp_path):
    arrays = basicmotions_continuous(SHARED / "basicmotions.npz")
    np.savez(tmp_path / "bm.npz", **arrays)
    rs = load_recordings(tmp_path / "bm.npz")
    assert len(rs.recordings) == 8 and all(len(r.X) == 1000 for r in rs.recordings)
    assert np.bincount(np.concatenate([r.y for r in rs.recordings])).tolist() == [2000] * 4


def test_clm_over_classifier_scores_groups_frames_and_rejects_with_its_background():
    from handflow.plugins.segmenter.compatibility import evidence_band, score_evidence

    evidence = score_evidence(np.array([[3.0, 0.0], [2.0, 1.0], [0.0, 2.5]]))
    assert np.allclose(evidence.sum(axis=1), 1) and evidence[0, 0] > evidence[1, 0] > 0.5 > evidence[2, 0]
    band = evidence_band(evidence, width=4, history=2)
    assert band.shape == (2, 3, 4) and np.allclose(band[:, :, 2:], 0) and np.allclose(band[:, 2], 0)
    assert band[0, 0, 0] > 0 > band[0, 1, 0]  # frames 0,1 lean to class 0 together; frame 2 does not
    four = evidence_band(np.tile([0.4, 0.2, 0.2, 0.2], (3, 1)), width=2, history=2)
    assert four[0, 0, 0] > 0 > four[1, 0, 0]  # above chance (1/4) supports, below repels, with 4 classes

    X, y = _synthetic_recordings(0)
    method = REGISTRY["clm_dtw"]
    fitted = method.fit({c: [X[y == c]] for c in (0, 1, 2)}, {"window": 20}, seed=0)
    state = method.prepare(fitted, X)
    kept = method.labels(fitted, state, reject=-np.inf)
    assert np.mean(kept == y) > 0.8  # the CLM groups the classifier's evidence into the right segments
    assert np.all(method.labels(fitted, state, reject=np.inf) == -1)  # a null class above every score takes all
    dropped = method.labels(fitted, state, reject=-np.inf, drop=2)
    assert not np.any(dropped == 2)  # pseudo-unknown: class 2's layer is gone


def test_clm_over_scores_rejects_on_its_scorers_scale_and_sweep():
    """The rejection of clm_<scorer> is the scorer's threshold (a null class scoring it), swept over
    the scorer's own quantiles: at each threshold the CLM rejects about the frames the scorer does,
    grouped, not far more (the coarse background band rejected half the known frames in one step,
    docs/segmentation.md)."""
    X, y = _synthetic_recordings(0)
    method = REGISTRY["clm_dtw"]
    fitted = method.fit({c: [X[y == c]] for c in (0, 1, 2)}, {"window": 20}, seed=0)
    state = method.prepare(fitted, X)
    grid = method.reject_grid(fitted, [state])
    assert np.array_equal(grid, method.scorer.reject_grid(fitted, [state], method.thresholds))
    assert grid[0] == -np.inf and grid[-1] == np.inf and len(grid) == method.thresholds + 2
    for threshold in grid[1:-1]:
        clm, scorer = method.labels(fitted, state, threshold), method.scorer.labels(fitted, state, threshold)
        assert abs(np.mean(clm == -1) - np.mean(scorer == -1)) < 0.15, threshold


def test_novelty_from_the_class_manifolds_rejects_what_the_classifier_labels_confidently():
    """Class 2 was never trained on: the classifier gives its frames to class 0 or 1, and only the
    manifolds' null model (the novelty term) sends them to the background, keeping the known frames."""
    X, y = _synthetic_recordings(0)
    segments = {c: [X[y == c]] for c in (0, 1)}
    novelty = NoveltyCLMMethod(DTWMethod())
    assert novelty.name == "clm_dtw_novelty" and all("delay" in p for p in novelty.grid(quick=True))
    assert {p["distance_z"] for p in novelty.grid(quick=True)} == {None}  # DTW has no features to measure
    assert {p["distance_z"] for p in REGISTRY["clm_minirocket_novelty"].grid(quick=True)} == {1.0, 2.0}
    fitted = novelty.fit(segments, {"window": 20, "delay": 8, "novelty": 0.25}, seed=0)
    state = novelty.prepare(fitted, X)
    unknown, known = y == 2, y != 2

    labels = novelty.labels(fitted, state, reject=0.1)
    assert np.mean(labels[unknown] == -1) > 0.9
    assert np.mean(labels[known] == y[known]) > 0.85
    tolerant = replace(fitted, params={**fitted.params, "novelty": 1e-6})
    scores, feature_novelty, proj, intensity = state
    assert feature_novelty is None
    in_range = (scores, None, proj, np.ones_like(intensity))
    plain_labels = novelty.labels(tolerant, in_range, reject=0.1)  # nothing novel: the classifier's evidence
    assert np.mean(plain_labels[unknown] == -1) < 0.2  # the same background without the novelty term
    by_intensity = novelty.labels(tolerant, state, reject=0.1)  # class 2 moves unlike 0 and 1 (its ranges)
    assert np.mean(by_intensity[unknown] == -1) > 0.8 and np.mean(by_intensity[known] == y[known]) > 0.85

    dropped = novelty.labels(fitted, state, reject=0.1, drop=1)  # pseudo-unknown: column and manifold go
    assert not np.any(dropped == 1) and np.mean(dropped[y == 1] == -1) > 0.5


def _indistinguishable_recordings(tmp_path):
    """Four recordings of three 'classes' drawn from one and the same noise: no operating point can
    keep known frames and reject a left-out class better than rejecting everything."""
    rng = np.random.default_rng(0)
    arrays = {"class_names": np.array(["a", "b", "c"])}
    for k in range(4):
        y = np.repeat(rng.permutation(np.repeat([0, 1, 2], 2)), 30)
        arrays[f"X_r{k}"], arrays[f"y_r{k}"] = rng.normal(size=(len(y), 2)), y
    np.savez(tmp_path / "n.npz", **arrays)
    return load_recordings(tmp_path / "n.npz")


def test_rejection_is_switched_off_when_nothing_beats_rejecting_everything(tmp_path):
    data = _indistinguishable_recordings(tmp_path)
    said = []
    ev = RecordingsEvaluator(data, methods=("dtw_1nn",), quick=True, progress=said.append)  # the default: fallback
    result = ev.evaluate()
    res = result["methods"]["dtw_1nn"]
    assert result["parameters"]["calibration"]["mode"] == "fallback"
    assert all(
        f["selected"]["rejection"] == "off" and f["selected"]["validation_objective"] <= 0.55 for f in res["folds"]
    )
    assert res["rejection_off_folds"] == 4 and sum("dtw_1nn" in s and "rejection off" in s for s in said) == 4
    assert res["known_accuracy"] == res["no_rejection"]["known_accuracy"]  # every frame keeps its best label
    assert "rejection is off in 4 of 4 folds" in res["calibration_note"]
    strict = RecordingsEvaluator(data, methods=("dtw_1nn",), quick=True, calibration="strict").evaluate()
    strict = strict["methods"]["dtw_1nn"]
    assert "strict" not in strict and "the default calibration (fallback) switches" in strict["calibration_note"]
    assert {f["selected"]["rejection"] for f in strict["folds"]} == {"calibrated"} and strict[
        "rejection_off_folds"
    ] == 0
    assert res["strict"] == {k: strict[k] for k in res["strict"]}  # what the objective alone would give
    assert strict["known_accuracy"] < res["known_accuracy"]


def test_derived_features_are_chosen_per_method_on_validation(tmp_path):
    arrays = {"class_names": np.array(["a", "b", "c"])}
    for k in range(4):
        arrays[f"X_r{k}"], arrays[f"y_r{k}"] = _synthetic_recordings(k)
    np.savez(tmp_path / "s.npz", **arrays)
    said = []
    ev = RecordingsEvaluator(
        load_recordings(tmp_path / "s.npz"),
        methods=("dtw_1nn",),
        quick=True,
        derived=("none", "velocities"),
        detail=said.append,
    )
    out = ev.evaluate()
    assert out["parameters"]["derived"] == ["none", "velocities"]
    screened = [m for m in said if "dtw_1nn screen" in m]
    refined = [m for m in said if "dtw_1nn refine" in m]
    assert len(screened) == 2 * 4 and len(refined) == 4  # both choices screened, the better refined, every fold
    for fold, line in zip(out["methods"]["dtw_1nn"]["folds"], refined):
        assert f"'derived': '{fold['selected']['derived']}'" in line
    with pytest.raises(ValueError, match="derived features"):
        RecordingsEvaluator(ev.data, derived=("accelerations",))


def test_a_calibration_that_rejects_everything_is_explained():
    from handflow.plugins.segmenter.evaluation._report import _degenerate_calibration

    truth = np.array([0, 0, 1, 1, 1, -1])
    everything = np.full(6, -1)
    closed = {"known_accuracy": 0.4}
    note = _degenerate_calibration(truth, everything, [0, 1], [{"validation_objective": 0.5}] * 3, closed)
    assert "100% of the known frames are rejected" in note and "without rejection 0.400" in note
    assert _degenerate_calibration(truth, everything, [0, 1], [{"validation_objective": 0.7}], closed) is None
    assert _degenerate_calibration(truth, truth, [0, 1], [{"validation_objective": 0.5}], closed) is None


def test_velocities_are_causal_steps():
    X = np.random.default_rng(1).normal(size=(20, 3))
    V = derive(X, "velocities")
    assert V.shape == (20, 6) and np.array_equal(V[:, :3], X) and not V[0, 3:].any()
    assert np.allclose(V[1:, 3:], X[1:] - X[:-1])
    assert np.array_equal(derive(X[:7], "velocities"), V[:7])  # a stream's prefix gets the same features
    assert np.array_equal(derive(X, "none"), X)
    with pytest.raises(ValueError, match="derived features must be one of"):
        derive(X, "speed")


def test_a_joint_classifier_is_refitted_for_the_pseudo_unknowns_of_the_calibration():
    """The ridge of MiniRocket is fitted on all classes at once: with class 2's column merely
    dropped, the other columns were still trained to be low on its frames. The calibration's
    pseudo-unknown is therefore a model refitted without it, which is as sure of class 2's frames
    as of a class it never saw; per-class models just leave the class's model out."""
    pytest.importorskip("aeon")
    X, y = _synthetic_recordings(0)
    segments = {c: [X[y == c]] for c in (0, 1, 2)}
    method = REGISTRY["minirocket"]
    fitted = method.fit(segments, {"window": 16}, seed=0)
    unseen = method.without_class(fitted, segments, 2, seed=0)
    assert unseen.classes == [0, 1] and unseen.model.classes_ == [0, 1]
    dropped = method.prepare(fitted, X)[y == 2][:, :2].max(axis=1)
    refitted = method.prepare(unseen, X)
    assert refitted.shape == (len(X), 2)  # a binary ridge still scores one column per class
    refitted = refitted[y == 2].max(axis=1)
    assert np.median(refitted) > np.median(dropped) + 0.2  # a class never seen gets confident scores
    assert REGISTRY["clm_minirocket"].without_class(fitted, segments, 2, seed=0).classes == [0, 1]
    manifolds = fit_recording_models({str(c): s for c, s in segments.items()}, delay=4, n_steps=20)
    novelty = REGISTRY["clm_minirocket_novelty"]
    both = Fitted((fitted, manifolds), [0, 1, 2], {"window": 16, "delay": 4, "novelty": 0.25, "distance_z": 2.0})
    unseen = novelty.without_class(both, segments, 2, seed=0)  # the ridge refitted, class 2's manifold left out
    assert unseen.classes == [0, 1] and unseen.model[1].classes == ["0", "1"]
    labels = novelty.labels(unseen, novelty.prepare(unseen, X), reject=0.5)
    assert set(np.unique(labels)) <= {-1, 0, 1}
    assert REGISTRY["dtw_1nn"].without_class(fitted, segments, 2, seed=0) is None
    two = {c: segments[c] for c in (0, 1)}  # one class left: no ridge; the column is dropped instead
    assert method.without_class(method.fit(two, {"window": 16}, seed=0), two, 1, seed=0) is None
    assert REGISTRY["ukr_clm"].without_class(fitted, segments, 2, seed=0) is None


def test_a_class_recorded_in_one_recording_only_is_left_out_of_the_folds_that_lack_it(tmp_path):
    """Class c is labelled in r0 only: the fold holding r0 out trains without c (and says so), the
    inner splits without it use their models as they are, and the evaluation runs to the end."""
    pytest.importorskip("aeon")
    arrays = {"class_names": np.array(["a", "b", "c"])}
    for k in range(4):
        X, y = _synthetic_recordings(k)
        arrays[f"X_r{k}"], arrays[f"y_r{k}"] = X, np.where((y == 2) & (k > 0), -1, y)
    np.savez(tmp_path / "s.npz", **arrays)
    said = []
    ev = RecordingsEvaluator(
        load_recordings(tmp_path / "s.npz"), methods=("minirocket",), quick=True, progress=said.append
    )
    res = ev.evaluate()["methods"]["minirocket"]
    assert [f["untrained_classes"] for f in res["folds"]] == [["c"], [], [], []]
    assert any("no training segment of ['c']" in s for s in said)
    assert sum("min to go" in s for s in said) == 3  # an estimate after every fold but the last
    r0 = ev.folds_[0]
    assert not np.any(r0.labels["minirocket"] == 2)  # a model without c cannot label it
    assert res["known_accuracy"] > 0.5

    arrays = {"class_names": np.array(["a", "b"])}
    for k in range(3):
        X, y = _synthetic_recordings(k)
        arrays[f"X_r{k}"], arrays[f"y_r{k}"] = X, np.where(k == 0, y % 2, np.where(y == 0, 0, -1))
    np.savez(tmp_path / "one.npz", **arrays)  # b only in r0: holding r0 out leaves one class to train
    with pytest.raises(ValueError, match="needs at least 2: add recordings"):
        RecordingsEvaluator(load_recordings(tmp_path / "one.npz"), methods=("dtw_1nn",), quick=True).evaluate()


def _odd(kind: str, k: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """Recording k of an odd but valid dataset (three classes a, b, c)."""
    X, y = _synthetic_recordings(k)
    if kind == "constant column":
        return np.c_[X, np.full(len(X), 7.0)], y
    if kind == "one channel":
        return X[:, :1], y
    if kind == "huge values":
        return X * 1e6 + 3e7, y
    if kind == "segments of 2-5 frames":
        n = rng.integers(2, 6, size=6)
        return np.vstack([X, rng.normal(size=(n.sum(), 2))]), np.r_[y, np.repeat(np.arange(6) % 3, n)]
    if kind == "an unlabelled recording":
        return X, np.full(len(y), -1) if k == 3 else y
    assert kind == "a 6-frame recording"
    return (rng.normal(size=(6, 2)), np.array([0, 0, 1, 1, 2, 2])) if k == 3 else (X, y)


@pytest.mark.parametrize(
    "kind",
    [
        "constant column",
        "one channel",
        "huge values",
        "segments of 2-5 frames",
        "an unlabelled recording",
        "a 6-frame recording",
    ],
)
def test_odd_but_valid_recordings_are_evaluated_to_the_end(tmp_path, kind):
    """Real recording sets come in shapes the shipped ones do not have; each must be evaluated."""
    rng = np.random.default_rng(0)
    arrays = {"class_names": np.array(["a", "b", "c"])}
    for k in range(4):
        arrays[f"X_r{k}"], arrays[f"y_r{k}"] = _odd(kind, k, rng)
    np.savez(tmp_path / "odd.npz", **arrays)
    methods = ("dtw_1nn", "hmm") if importlib.util.find_spec("hmmlearn") else ("dtw_1nn",)  # hmm: an extra
    out = RecordingsEvaluator(load_recordings(tmp_path / "odd.npz"), methods=methods, quick=True).evaluate()
    for res in out["methods"].values():
        assert len(res["folds"]) == 4 and 0 <= res["open_set_accuracy"] <= 1
