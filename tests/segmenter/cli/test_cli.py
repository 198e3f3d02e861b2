import json
from pathlib import Path

import numpy as np
import pytest

from handflow.framework.graphs.model import load_graph
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.segmenter import EXPERIMENTS, METHODS, load_candidates
from handflow.plugins.segmenter.cli import register_evaluate, register_train_classes
from handflow.plugins.segmenter.models import ModelsMissingError
from handflow.plugins.segmenter.nodes import OnlineCLMNode
from tests.conftest import run_command
from tests.segmenter.datasets.test_recordings import _indistinguishable_recordings, _synthetic_recordings
from tests.segmenter.datasets.test_trajectories import write_csv_dataset


@pytest.fixture(scope="module")
def csv_dataset(tmp_path_factory, synthetic):
    return write_csv_dataset(tmp_path_factory.mktemp("ds") / "letters", synthetic)


def test_train_classes_writes_loadable_models(tmp_path, csv_dataset, synthetic):
    assert run_command(register_train_classes, [str(csv_dataset), "--out", str(tmp_path / "m"), "--steps", "30"]) == 0
    index = json.loads((tmp_path / "m" / "classes.json").read_text())
    assert sorted(index["classes"]) == ["A", "B", "C", "D"]
    cands = load_candidates(tmp_path / "m")
    assert cands.project(synthetic.test[0].data).latent_time.shape == (len(synthetic.test[0].data), 4)


def test_missing_models_say_how_to_train(tmp_path):
    with pytest.raises(ModelsMissingError, match="train-classes"):
        load_candidates(tmp_path)


def test_bad_dataset_exits_2(tmp_path, capsys):
    assert run_command(register_evaluate, [str(tmp_path / "missing")]) == 2
    assert "does not exist" in capsys.readouterr().err


@pytest.mark.slow
def test_quick_evaluation_json_and_plots(tmp_path, csv_dataset, capsys):
    code = run_command(
        register_evaluate, [str(csv_dataset), "--quick", "--json", "--steps", "50", "--plots", str(tmp_path / "plots")]
    )
    out = capsys.readouterr()
    assert code == 0
    result = json.loads(out.out)
    assert set(result["methods"]) == set(METHODS)
    for method in METHODS:
        for exp in EXPERIMENTS:
            r = result["methods"][method][exp]
            assert 0.0 <= r["share_perfect"] <= r["share_ge_85"] <= 1.0
            assert r["cases"] and all(0.0 <= c["correct"] <= 1.0 for c in r["cases"])
    assert result["methods"]["ukr_clm"]["single"]["mean_correct"] > 0.8
    assert set(result["parameters"]["selected"]) == set(METHODS)
    strong = result["methods"]["ukr_clm"]["reversed_rejection"]["strong_background"]
    assert strong["mean_correct"] >= result["methods"]["ukr_clm"]["reversed_rejection"]["mean_correct"]
    assert "validation" in out.err  # progress on stderr
    assert (tmp_path / "plots" / "summary.png").stat().st_size > 0
    assert (tmp_path / "plots" / "concatenated_ukr_clm.png").exists()
    assert np.isfinite(result["runtime_s"])


def test_select_is_refused_for_continuous_recordings(tmp_path, capsys):
    np.savez(tmp_path / "c.npz", class_names=np.array(["a"]), X_r=np.zeros((4, 2)), y_r=np.zeros(4, int))
    assert run_command(register_evaluate, [str(tmp_path / "c.npz"), "--select", "recognition"]) == 2
    assert "--select applies to labelled trajectories" in capsys.readouterr().err


DEMO = Path(__file__).resolve().parents[3] / "recordings" / "segmenter_demo"


def test_train_classes_on_recordings_calibrates_the_background_of_the_online_node(tmp_path, capsys):
    out = tmp_path / "m"
    assert run_command(register_train_classes, [str(DEMO), "--delay", "4", "--steps", "30", "--out", str(out)]) == 0
    provenance = json.loads((out / "classes.json").read_text())["provenance"]
    factor = provenance["background_factor"]
    assert provenance["background_calibration"]["rejection"] == "calibrated" and factor > 0
    assert provenance["background_calibration"]["validation_objective"] > 0.55
    assert f"background_factor {factor:g} at history 10" in capsys.readouterr().err
    assert provenance["history"] == 10  # the history the level was calibrated at, the node's
    assert NodeHarness(OnlineCLMNode, {"models": str(out)}).setup().node.segmenter.background_factor == factor
    given = NodeHarness(OnlineCLMNode, {"models": str(out), "background_factor": 3.0}).setup()
    assert given.node.segmenter.background_factor == 3.0  # the parameter overrides the calibrated level


def test_train_classes_with_params_trains_ukr_clms_choice_of_most_folds(tmp_path, capsys):
    folds = [
        {
            "recording": r,
            "selected": {
                "delay": d,
                "history": 20,
                "derived": "velocities",
                "normalise": "training",
                "reject": 0.25,
                "validation_objective": 0.7,
                "rejection": "calibrated",
            },
        }
        for r, d in (("rec0", 4), ("rec1", 6), ("rec2", 4))
    ]
    (tmp_path / "r.json").write_text(json.dumps({"methods": {"ukr_clm": {"folds": folds}}}))
    out = tmp_path / "m"
    argv = [str(DEMO), "--steps", "20", "--out", str(out), "--params", str(tmp_path / "r.json")]
    assert run_command(register_train_classes, argv) == 0
    index = json.loads((out / "classes.json").read_text())
    assert index["provenance"]["background_factor"] == 0.25  # the chosen level, not calibrated again
    assert index["provenance"]["background_calibration"]["params_from"] == str(tmp_path / "r.json")
    model = np.load(out / index["classes"][next(iter(index["classes"]))])
    meta = json.loads(str(model["metadata"])) if "metadata" in model.files else {}
    assert "delay 4, history 20" in capsys.readouterr().err and json.dumps(meta).count('"velocities"') >= 1
    # the chosen history reaches the online node, as the shipped gesture graphs run it, unless a graph sets it
    assert index["provenance"]["history"] == 20
    for graph in ("recognise_gestures", "segment_gestures"):
        params = dict(load_graph(graph).nodes["segmenter"].spec.params, models=str(out))
        assert NodeHarness(OnlineCLMNode, params).setup().node.segmenter.history == 20, graph
    given = NodeHarness(OnlineCLMNode, {"models": str(out), "history": 10}).setup()
    assert given.node.segmenter.history == 10  # the parameter overrides the choice
    for fold in folds:  # a normalisation train-classes does not train with is said, not silently dropped
        fold["selected"]["normalise"] = "recording"
    (tmp_path / "rec.json").write_text(json.dumps({"methods": {"ukr_clm": {"folds": folds}}}))
    assert run_command(register_train_classes, [*argv[:-1], str(tmp_path / "rec.json")]) == 0
    assert "warning: the evaluation chose normalisation 'recording'" in capsys.readouterr().err
    (tmp_path / "bad.json").write_text(json.dumps({"methods": {"dtw_1nn": {"folds": folds}}}))
    assert run_command(register_train_classes, [*argv[:-1], str(tmp_path / "bad.json")]) == 2
    assert "has no parameters for ['ukr_clm']" in capsys.readouterr().err


def test_train_classes_says_when_rejection_cannot_be_calibrated(tmp_path, capsys):
    data = _indistinguishable_recordings(tmp_path)  # three 'classes' of one and the same noise
    out = tmp_path / "m"
    assert run_command(register_train_classes, [data.source, "--delay", "2", "--steps", "20", "--out", str(out)]) == 0
    assert "rejection cannot be calibrated on this data" in capsys.readouterr().err
    provenance = json.loads((out / "classes.json").read_text())["provenance"]
    assert provenance["background_factor"] == 0 and provenance["background_calibration"]["rejection"] == "off"
    assert NodeHarness(OnlineCLMNode, {"models": str(out)}).setup().node.segmenter.background_factor == 0


@pytest.mark.slow  # a whole evaluation (docs/testing.md)
def test_folds_over_processes_give_the_same_json_as_one_after_the_other(tmp_path, capsys):
    """``--jobs 3`` runs the folds over three processes (one BLAS thread each): every figure, label
    and selected parameter of the JSON equals that of ``--jobs 1`` (docs/segmentation.md)."""
    arrays = {"class_names": np.array(["a", "b", "c"])}
    for k in range(3):
        arrays[f"X_r{k}"], arrays[f"y_r{k}"] = _synthetic_recordings(k)
    np.savez(tmp_path / "s.npz", **arrays)
    results = []
    for jobs in ("1", "3"):
        one_view = ["--normalise", "training", "--derived", "none"]  # more views: the same computation in a worker
        args = [str(tmp_path / "s.npz"), "--quick", "--json", *one_view, "--methods", "ukr_only,dtw_1nn"]
        args += ["--jobs", jobs]
        assert run_command(register_evaluate, args) == 0
        result = json.loads(capsys.readouterr().out)
        assert result.pop("runtime_s") > 0 and result.pop("timing")["folds"]
        results.append(result)
    assert results[0] == results[1]
    assert [f["recording"] for f in results[1]["methods"]["ukr_only"]["folds"]] == ["r0", "r1", "r2"]


def test_a_fold_that_fails_in_a_worker_stops_the_evaluation_with_its_error(tmp_path, capsys):
    arrays = {"class_names": np.array(["a", "b"])}
    for k in range(3):
        X, y = _synthetic_recordings(k)
        arrays[f"X_r{k}"], arrays[f"y_r{k}"] = X, np.where(k == 0, y % 2, np.where(y == 0, 0, -1))
    np.savez(tmp_path / "one.npz", **arrays)  # b only in r0: holding r0 out leaves one class to train
    args = [str(tmp_path / "one.npz"), "--quick", "--methods", "dtw_1nn", "--jobs", "2"]
    assert run_command(register_evaluate, args) == 2
    assert "needs at least 2: add recordings" in capsys.readouterr().err
