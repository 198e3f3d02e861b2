"""Enrolment (docs/segmentation.md, "Enrolment")."""

from __future__ import annotations

import numpy as np
import pytest

from handflow.plugins.segmenter.cli import format_stream_table, register_evaluate
from handflow.plugins.segmenter.datasets import (
    EnrolmentError,
    Recording,
    enrolment_recording,
    enrolment_split,
    load_recordings,
    session_aligned,
)
from handflow.plugins.segmenter.evaluation import RecordingsEvaluator, frame_metrics
from handflow.plugins.segmenter.evaluation import _enrolment as enrolment_module
from handflow.plugins.segmenter.evaluation._enrolment import ENROL_MARGIN
from tests.conftest import run_command
from tests.segmenter.datasets.test_recordings import _synthetic_recordings

#            a a b b b a a c c - b b c c a   (c unknown below; '-' unlabelled; the lone b is too short)
LABELS = np.array([0, 0, 1, 1, 1, 0, 0, 2, 2, -1, 1, 1, 2, 2, 0])


def test_enrolment_takes_the_first_k_segments_of_each_known_class_and_scores_the_frames_after_them():
    mask, end = enrolment_split(LABELS, [0, 1], 1)
    assert np.flatnonzero(mask).tolist() == [0, 1, 2, 3, 4] and end == 5
    mask, end = enrolment_split(LABELS, [0, 1], 2)  # the second a and b; c, not known, is never enrolled
    assert np.flatnonzero(mask).tolist() == [0, 1, 2, 3, 4, 5, 6, 10, 11] and end == 12
    rec, start = enrolment_recording(Recording("r", np.arange(15.0)[:, None], LABELS), [0, 1], 2)
    assert start == 12 and rec.name == "r (enrolment)" and len(rec.X) == 12
    assert rec.y.tolist() == [0, 0, 1, 1, 1, 0, 0, -1, -1, -1, 1, 1]  # c between the enrolment segments: unlabelled
    with pytest.raises(EnrolmentError, match="class 'b' has 2"):
        enrolment_split(LABELS, [0, 1], 3, ["a", "b", "c"])


def _session_set(path, shifted: bool = False, seeds=((0, 10), (1, 11), (2, 12), (3, 13))):
    """Synthetic recordings of three motion classes, one per tuple of ``seeds`` made of one part per
    seed (:func:`_synthetic_recordings`: each class twice per part); ``shifted``: each session moved
    and scaled as a new glove fit would."""
    arrays = {"class_names": np.array(["a", "b", "c"])}
    for k, parts in enumerate(seeds):
        X, arrays[f"y_r{k}"] = (np.concatenate(part) for part in zip(*map(_synthetic_recordings, parts)))
        arrays[f"X_r{k}"] = (1.0 + 0.8 * k) * X + np.array([2.0 * k, -1.5 * k]) if shifted else X
    np.savez(path, **arrays)
    return load_recordings(path)


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    return _session_set(tmp_path_factory.mktemp("enrol") / "s.npz")


def test_without_enrolment_the_evaluation_is_unchanged(sessions):
    default = RecordingsEvaluator(sessions, methods=("dtw_1nn",), quick=True).evaluate()
    off = RecordingsEvaluator(sessions, methods=("dtw_1nn",), quick=True, enroll=0).evaluate()
    assert off.pop("timing") and default.pop("timing")  # wall times: the machine's
    assert off == default
    assert "enrolment" not in default["methods"]["dtw_1nn"] and "enroll" not in default["parameters"]


def test_with_and_without_enrolment_are_scored_on_the_same_frames_after_it(sessions):
    plain = RecordingsEvaluator(sessions, methods=("dtw_1nn",), quick=True)
    plain.evaluate()
    ev = RecordingsEvaluator(sessions, methods=("dtw_1nn",), quick=True, enroll=1, enrol_adaptations=("refit", "align"))
    res = ev.evaluate()
    report = res["methods"]["dtw_1nn"]["enrolment"]
    assert res["parameters"]["enroll"] == 1 and report["adaptation"] == "refit"
    for f, p in zip(ev.folds_, plain.folds_):
        assert f.scored_from == enrolment_split(f.truth, ev.known, 1)[1] == report["scored_from"][f.recording]
        assert np.array_equal(f.labels["dtw_1nn"], p.labels["dtw_1nn"])  # the fit without enrolment
    truth = np.concatenate([f.truth[f.scored_from :] for f in ev.folds_])
    without = np.concatenate([p.labels["dtw_1nn"][f.scored_from :] for f, p in zip(ev.folds_, plain.folds_)])
    assert report["without_enrolment"] == frame_metrics(truth, without, ev.known)
    for adaptation in ("refit", "align"):
        enrolled = np.concatenate([f.enrolled[adaptation]["dtw_1nn"][f.scored_from :] for f in ev.folds_])
        assert report["adaptations"][adaptation]["with_enrolment"] == frame_metrics(truth, enrolled, ev.known)
        assert any(not np.array_equal(f.enrolled[adaptation]["dtw_1nn"], f.labels["dtw_1nn"]) for f in ev.folds_)
    assert report["with_enrolment"] == report["adaptations"]["refit"]["with_enrolment"]
    assert report["gain"] == report["open_set_accuracy"] - report["open_set_accuracy_without_enrolment"]
    assert "after the enrolment: open-set accuracy" in format_stream_table(res)


def test_the_session_alignment_learns_offset_and_scale_from_the_enrolment_frames_only():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(15, 2))
    aligned = session_aligned(Recording("r", 3.0 + 2.0 * X, LABELS), [0, 1], 1)
    enrolled = [aligned.X[:2], aligned.X[2:5]]  # the first a and the first b
    assert np.allclose(np.mean([e.mean(axis=0) for e in enrolled], axis=0), 0)  # each class weighs alike
    assert np.allclose(session_aligned(Recording("r", X, LABELS), [0, 1], 1).X, aligned.X)  # offset and scale gone
    later = np.r_[X[:5], 10 * X[5:]]
    assert np.allclose(session_aligned(Recording("r", later, LABELS), [0, 1], 1).X[:5], aligned.X[:5])


def test_a_recording_without_k_segments_of_a_known_class_stops_the_evaluation_saying_what_to_change(tmp_path, capsys):
    arrays = {"class_names": np.array(["a", "b"])}
    for k in range(3):
        arrays[f"X_r{k}"] = np.random.default_rng(k).normal(size=(40, 2))
        arrays[f"y_r{k}"] = np.repeat([0, 1, 0, 1], 10) if k else np.repeat([0, 1, 0, 0], 10)
    np.savez(tmp_path / "s.npz", **arrays)
    args = [str(tmp_path / "s.npz"), "--quick", "--methods", "dtw_1nn", "--jobs", "1", "--enroll", "2"]
    assert run_command(register_evaluate, args) == 2
    err = capsys.readouterr().err
    assert "--enroll 2: recording 'r0' has fewer segments than the 2 to enrol: class 'b' has 1" in err
    assert "lower --enroll, or leave such classes out with --known" in err


@pytest.mark.parametrize("shifted", [False, True])
def test_the_chosen_adaptation_is_one_of_the_others_per_fold_and_its_labels_are_that_ones(sessions, tmp_path, shifted):
    data = _session_set(tmp_path / "s.npz", shifted=True) if shifted else sessions
    ev = RecordingsEvaluator(
        data,
        methods=("dtw_1nn",),
        quick=True,
        normalise="training",
        enroll=1,
        enrol_adaptations=("chosen", "refit", "align"),
    )
    res = ev.evaluate()
    report = res["methods"]["dtw_1nn"]["enrolment"]
    assert report["adaptation"] == "chosen"
    chosen = report["adaptations"]["chosen"]["chosen"]
    assert set(chosen) == set(data.names()) and set(chosen.values()) <= {"none", "refit", "align"}
    for f in ev.folds_:
        picked = f.selected["dtw_1nn"]["enrol_adaptation"]
        assert chosen[f.recording] == picked
        expected = f.labels["dtw_1nn"] if picked == "none" else f.enrolled[picked]["dtw_1nn"]
        assert np.array_equal(f.enrolled["chosen"]["dtw_1nn"], expected)
    if shifted:  # sessions that differ in offset and scale under the training z-score: the alignment wins
        assert set(chosen.values()) == {"align"} and report["gain"] > 0.1
        for f in ev.folds_:
            inner = f.selected["dtw_1nn"]["enrol_validation"]
            assert inner["align"] >= max(inner.values()) and inner["align"] >= inner["none"] + ENROL_MARGIN
        assert "(chosen: align in 4; gain" in format_stream_table(res)


@pytest.mark.slow  # a whole evaluation (docs/testing.md)
def test_without_an_inner_fold_gain_of_the_margin_the_enrolment_is_not_used(tmp_path, monkeypatch):
    monkeypatch.setattr(enrolment_module, "ENROL_MARGIN", 1.0)  # no adaptation gains a whole unit of accuracy
    # the fewest recordings (three), of one part each (a quarter of the fits of four two-part sessions), shifted: the
    # alignment labels every inner fold better than no enrolment, by less than the margin
    data = _session_set(tmp_path / "s.npz", shifted=True, seeds=((10,), (11,), (12,)))
    ev = RecordingsEvaluator(
        data, methods=("ukr_clm", "ukr_clm_online"), quick=True, normalise="training", derived=("none",), enroll=1
    )
    report = ev.evaluate()["methods"]["ukr_clm_online"]["enrolment"]
    assert set(report["adaptations"]["chosen"]["chosen"].values()) == {"none"} and report["gain"] == 0
    for f in ev.folds_:
        inner = f.selected["ukr_clm"]["enrol_validation"]
        assert set(inner) == {"none", "refit", "align"}
        assert inner["align"] > inner["none"]  # better on the inner folds: only the margin keeps it out
        assert all(np.array_equal(f.enrolled["chosen"][m], f.labels[m]) for m in ("ukr_clm", "ukr_clm_online"))
