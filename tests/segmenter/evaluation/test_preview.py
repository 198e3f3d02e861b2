"""The preview protocol on continuous recordings (docs/segmentation.md, "Which protocol when"):
candidates scored once on the leave-one-recording-out folds, one choice per method for all
folds, its labels the reported ones; labels of classes outside ``--known`` never choose."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from handflow.plugins.segmenter.cli import register_evaluate, register_train_classes
from handflow.plugins.segmenter.datasets import Recording, load_recordings
from handflow.plugins.segmenter.evaluation import REGISTRY, RecordingsEvaluator
from handflow.plugins.segmenter.evaluation._fidelity import PREVIEW
from tests.conftest import run_command

DEMO = Path(__file__).parents[3] / "recordings" / "segmenter_demo"
KNOWN = ["circle", "wave"]  # "rest" is unknown: its frames must be rejected and never choose
METHODS = ("ukr_clm", "ukr_clm_online", "dtw_1nn")
VIEWS = {"normalise": ("training", "recording"), "derived": ("none",)}  # two candidates: a screen, one refined


@pytest.fixture(scope="module")
def demo():
    return load_recordings(DEMO)


@pytest.fixture(scope="module")
def preview(demo):
    """The preview of the shipped recordings and its evaluator (the folds' labels, the fits)."""
    lines = []
    ev = RecordingsEvaluator(demo, KNOWN, METHODS, quick=True, preview=True, progress=lines.append, **VIEWS)
    return ev, ev.evaluate(), lines


def test_the_preview_declares_its_protocol_and_why_it_can_be_optimistic(preview):
    _, result, lines = preview
    assert result["protocol"]["name"] == "preview" and result["protocol"]["optimistic"] is True
    assert "best_score_" in result["protocol"]["reason"]
    assert "preview" in result["parameters"]["protocol"]  # still describes the folds
    assert result["parameters"]["recordings"] == ["rec0", "rec1", "rec2"]
    assert set(result["methods"]) == set(METHODS)
    for r in result["methods"].values():  # the nested layout
        assert {"open_set_accuracy", "known_accuracy", "unknown_rejection", "folds"} <= set(r)
        assert r["unknown_rejection"] is not None  # "rest" is reported as unknown
    assert any("provisional ranking" in line for line in lines)  # the screen's table, on the progress


def test_every_fold_gets_the_one_choice_and_its_refined_fits_label_it(preview):
    ev, result, _ = preview
    for name, r in result["methods"].items():
        chosen = [f["selected"] for f in r["folds"]]
        assert all(s == chosen[0] for s in chosen), name
    method, selected = REGISTRY["dtw_1nn"], result["methods"]["dtw_1nn"]["folds"][0]["selected"]
    params = {k: selected[k] for k in ("window", "derived", "normalise")}
    for fold in ev.folds_:  # no final refit: the calibration's own fits label the held-out recording
        train, test = ev.views(fold.recording)[params["normalise"], params["derived"]]
        fitted = method.fit(ev._segments(train), params, 0, PREVIEW.refine)
        expected = method.labels(fitted, method.prepare(fitted, test.X), selected["reject"])
        np.testing.assert_array_equal(fold.labels["dtw_1nn"], expected)


def test_labels_of_unknown_classes_never_enter_the_choice(demo, preview):
    _, result, _ = preview
    rest = demo.class_names.index("rest")
    unlabelled = replace(
        demo, recordings=[Recording(r.name, r.X, np.where(r.y == rest, -1, r.y)) for r in demo.recordings]
    )
    choosing = ("ukr_clm", "dtw_1nn")  # the online method replays ukr_clm's choice
    blind = RecordingsEvaluator(unlabelled, KNOWN, choosing, quick=True, preview=True, **VIEWS).evaluate()
    for name in choosing:  # the same choice and the same known frames' figures; only the report of "rest" goes
        a, b = result["methods"][name], blind["methods"][name]
        assert [f["selected"] for f in a["folds"]] == [f["selected"] for f in b["folds"]], name
        assert a["known_accuracy"] == b["known_accuracy"] and b["unknown_rejection"] is None


def test_the_command_says_which_protocol_its_figures_come_from(capsys):
    argv = [str(DEMO), "--quick", "--preview", "--methods", "dtw_1nn", "--normalise", "training", "--derived", "none"]
    assert run_command(register_evaluate, argv) == 0
    assert capsys.readouterr().out.startswith("protocol: preview, optimistic — cross-validated grid search")
    assert run_command(register_evaluate, [*argv, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["protocol"]["name"] == "preview"


def test_train_classes_trains_the_models_a_preview_chose(preview, tmp_path, capsys):
    _, result, _ = preview
    (tmp_path / "preview.json").write_text(json.dumps(result))
    argv = [str(DEMO), "--out", str(tmp_path / "models"), "--params", str(tmp_path / "preview.json"), "--steps", "30"]
    assert run_command(register_train_classes, argv) == 0
    assert "optimistic: the settings were chosen on these same recordings" in capsys.readouterr().out
    provenance = json.loads((tmp_path / "models" / "classes.json").read_text())["provenance"]
    selected = result["methods"]["ukr_clm"]["folds"][0]["selected"]
    expected = 0.0 if selected["rejection"] == "off" else selected["reject"]
    assert provenance["background_factor"] == expected
    assert provenance["background_calibration"]["params_from"] == str(tmp_path / "preview.json")


def test_the_preview_refuses_what_belongs_to_the_nested_protocol(demo, tmp_path):
    with pytest.raises(ValueError, match="--preview takes no"):
        RecordingsEvaluator(demo, methods=("dtw_1nn",), preview=True, checkpoints=str(tmp_path))


def test_the_trajectory_preview_chooses_on_the_test_cases_it_reports(monkeypatch):
    from handflow.plugins.segmenter import LetterGenerator, candidate_set
    from handflow.plugins.segmenter.evaluation import Evaluator, TrajectoryProtocol
    from handflow.plugins.segmenter.models import train_class_models

    letters = LetterGenerator(n_classes=3, random_state=1, noise=0.01).dataset((3, 1, 1))
    sets = [candidate_set(train_class_models(letters, n_steps=30, random_state=0, headings=h)) for h in ((0, 1), ())]
    protocol = TrajectoryProtocol(nths=(1, 2), histories=(5,), runs=1, max_pairs=2)
    ev = Evaluator(letters, sets[0], protocol, alternatives=(sets[1],), preview=True)
    splits = []
    run = Evaluator.run
    monkeypatch.setattr(
        Evaluator, "run", lambda self, m, p, split, **kw: splits.append(split) or run(self, m, p, split, **kw)
    )
    result = ev.evaluate(("ukr_only", "dtw_1nn"))
    assert result["protocol"]["name"] == "preview" and result["parameters"]["protocol"]["choose_on"] == "test"
    assert set(splits) == {"test"}  # no validation round
    chosen = result["parameters"]["selection"]["ukr_only"]["headings"]
    assert all(len(h["folds"]) == 1 for h in chosen)  # no cross-fitted heading splits
    best = max(h["validation"] for h in chosen)  # the reported candidate set is the best on the test cases
    assert result["parameters"]["validation_score"]["ukr_only"] >= best - 0.01
