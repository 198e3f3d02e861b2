"""Labels with a lag (docs/segmentation.md, "Labels with a lag")."""

from __future__ import annotations

import numpy as np
import pytest

from handflow.plugins.segmenter.base import lagged
from handflow.plugins.segmenter.cli import format_stream_table
from handflow.plugins.segmenter.datasets import load_recordings
from handflow.plugins.segmenter.evaluation import REGISTRY, Choice, RecordingsEvaluator, frame_metrics, segment_f1


def test_lagged_labels_come_from_the_window_ending_lag_frames_later():
    labels = np.array([0, 0, 0, 1, 1, 2])
    assert lagged(labels, 0) is labels
    assert lagged(labels, 2).tolist() == [0, 1, 1, 2, 2, 2]  # the last frames keep the last label
    assert lagged(labels, 9).tolist() == [2] * 6
    with pytest.raises(ValueError, match="lag"):
        lagged(labels, -1)


@pytest.fixture(scope="module")
def three_classes(three_class_npz):
    return load_recordings(three_class_npz)


def test_the_evaluation_reports_accuracy_at_lag_zero_and_at_half_the_window(three_classes):
    ev = RecordingsEvaluator(three_classes, methods=("dtw_1nn",), quick=True)
    res = ev.evaluate()
    dtw = res["methods"]["dtw_1nn"]
    assert [f["half_window"] for f in dtw["folds"]] == [10] * 4  # the quick DTW window is 20 frames
    assert dtw["open_set_accuracy_at_lag"]["0"] == dtw["open_set_accuracy"]
    assert dtw["segment_f1_at_lag"]["0"] == dtw["segment_f1"]
    truth = np.concatenate([f.truth for f in ev.folds_])
    half = np.concatenate([lagged(f.labels["dtw_1nn"], 10) for f in ev.folds_])
    assert dtw["open_set_accuracy_at_lag"]["half_window"] == frame_metrics(truth, half, ev.known)["open_set_accuracy"]
    # the causal window labels boundaries late; the window centred on the frame does better
    assert dtw["open_set_accuracy_at_lag"]["half_window"] > dtw["open_set_accuracy_at_lag"]["0"]
    assert "at half the window (10/10/10/10 frames per fold)" in format_stream_table(res)


def test_an_evaluation_with_a_lag_labels_every_frame_from_the_later_window(three_classes):
    ev = RecordingsEvaluator(three_classes, methods=("dtw_1nn",), quick=True, lag=10)
    res = ev.evaluate()
    dtw = res["methods"]["dtw_1nn"]
    assert res["parameters"]["lag"] == 10
    for f in ev.folds_:  # the calibration saw lagged labels too; the figures are those of the lagged labels
        assert np.array_equal(f.labels["dtw_1nn"], lagged(f.unlagged["dtw_1nn"], 10))
    truth = np.concatenate([f.truth for f in ev.folds_])
    unlagged = np.concatenate([f.unlagged["dtw_1nn"] for f in ev.folds_])
    assert dtw["open_set_accuracy_at_lag"]["0"] == frame_metrics(truth, unlagged, ev.known)["open_set_accuracy"]
    assert dtw["open_set_accuracy"] == dtw["open_set_accuracy_at_lag"]["half_window"]  # lag 10 is half the window
    assert dtw["segment_f1"] == segment_f1([(f.truth, f.labels["dtw_1nn"]) for f in ev.folds_], ev.known)
    with pytest.raises(ValueError, match="lag"):
        RecordingsEvaluator(three_classes, methods=("dtw_1nn",), lag=-1)


def test_a_clm_over_a_scorer_rejects_only_where_its_scorer_may(three_classes):
    """The fallback rule gates clm_<scorer> by its scorer's best objective (docs/segmentation.md):
    a CLM objective above the margin keeps rejection off while the scorer's is not."""
    assert REGISTRY["clm_dtw"].rejects_with is REGISTRY["clm_dtw"].scorer
    assert REGISTRY["clm_dtw_novelty"].rejects_with is None and REGISTRY["dtw_1nn"].rejects_with is None
    ev = RecordingsEvaluator(three_classes, methods=("clm_dtw",), quick=True)
    choices = [(Choice({"window": 20}, 0.3, 0.8), -np.inf, lambda r: 0.9)]
    assert not ev._rule("clm_dtw", choices).fallback and not ev._rule("clm_dtw", choices, gate=0.7).fallback
    gated = ev._rule("clm_dtw", choices, gate=0.52)
    assert gated.fallback and gated.reject == -np.inf and gated.strict.reject == 0.3
