"""Continuous recordings: the inner folds choose the normalisation and the derived features per
method and fold; explicit values are overrides (docs/segmentation.md)."""

import json

import numpy as np
import pytest

from handflow.plugins.segmenter.cli import register_evaluate
from handflow.plugins.segmenter.datasets import load_recordings
from handflow.plugins.segmenter.evaluation import RecordingsEvaluator
from tests.conftest import run_command
from tests.segmenter.datasets.test_recordings import _synthetic_recordings


@pytest.fixture(scope="module")
def shifted(tmp_path_factory):
    """Four recordings, each "person" offset differently."""
    arrays = {"class_names": np.array(["a", "b", "c"])}
    for k in range(4):
        X, arrays[f"y_r{k}"] = _synthetic_recordings(k)
        arrays[f"X_r{k}"] = X + 0.5 * k
    path = tmp_path_factory.mktemp("shifted") / "s.npz"
    np.savez(path, **arrays)
    return path


def test_each_fold_labels_as_an_evaluation_given_its_choice(shifted):
    data = load_recordings(shifted)
    chosen = RecordingsEvaluator(
        data, methods=("dtw_1nn",), quick=True, normalise=("training", "recording"), derived=("none", "velocities")
    )
    choices = set()
    for held in data.names():
        fold = chosen.run_fold(held)
        selected = fold.selected["dtw_1nn"]
        choices.add(selected["normalise"])
        assert selected["normalise"] in ("training", "recording") and selected["derived"] in ("none", "velocities")
        given = RecordingsEvaluator(
            data, methods=("dtw_1nn",), quick=True, normalise=selected["normalise"], derived=(selected["derived"],)
        ).run_fold(held)
        assert given.selected["dtw_1nn"] == selected
        np.testing.assert_array_equal(given.labels["dtw_1nn"], fold.labels["dtw_1nn"])
    assert "recording" in choices  # each "person" is offset: the running normalisation wins somewhere


def test_the_cli_chooses_by_default_and_reports_the_choice_per_fold(shifted, capsys):
    argv = [str(shifted), "--methods", "dtw_1nn", "--quick", "--json", "--jobs", "1", "--pseudo-unknowns", "drop"]
    assert run_command(register_evaluate, argv) == 0
    chosen = json.loads(capsys.readouterr().out)
    assert chosen["parameters"]["normalisation"]["choices"] == ["training", "recording"]
    assert chosen["parameters"]["derived"] == ["none", "velocities"]
    folds = chosen["methods"]["dtw_1nn"]["folds"]
    assert all({"normalise", "derived"} <= set(f["selected"]) for f in folds)
    assert run_command(register_evaluate, [*argv, "--normalise", "training", "--derived", "none"]) == 0
    given = json.loads(capsys.readouterr().out)
    assert given["parameters"]["normalisation"]["mode"] == "training" and given["parameters"]["derived"] == ["none"]
    assert {(f["selected"]["normalise"], f["selected"]["derived"]) for f in given["methods"]["dtw_1nn"]["folds"]} == {
        ("training", "none")
    }
    with pytest.raises(ValueError, match="normalise must be one of"):
        RecordingsEvaluator(load_recordings(shifted), normalise=("training", "training"))
