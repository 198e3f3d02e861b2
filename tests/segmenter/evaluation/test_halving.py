"""Continuous recordings: successive halving over each method's candidates, the fidelities it
screens and refines with, the timing and warnings of the JSON (docs/segmentation.md, "successive
halving")."""

import json
import logging
import warnings
from collections import Counter

import numpy as np
import pytest

from handflow.plugins.segmenter.cli import register_evaluate
from handflow.plugins.segmenter.datasets import load_recordings
from handflow.plugins.segmenter.evaluation import REGISTRY, ChosenParameters, RecordingsEvaluator
from handflow.plugins.segmenter.evaluation._fidelity import FULL, REFINE, SCREEN
from handflow.plugins.segmenter.evaluation._selection import TIE_MARGIN, first_of_best, survivors
from handflow.plugins.segmenter.evaluation._third_party import counted_warnings, summary
from tests.conftest import run_command

UKR_SWEEP = np.array([0.0, 1 / 32, 1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0, 2.0, 4.0, 8.0, 16.0, 64.0])


def test_the_screen_keeps_the_best_third_in_candidate_order():
    assert survivors([0.5, 0.7, 0.69, 0.6]) == [1, 2]  # ceil(4 / 3) = 2, back in candidate order
    assert survivors([0.9]) == [0]
    assert survivors([0.6, 0.6, 0.6]) == [0]  # a tie keeps the earlier candidate
    assert survivors([0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]) == [4, 5, 6]


def test_a_tie_within_the_margin_goes_to_the_first_candidate():
    assert first_of_best([0.70, 0.70 + TIE_MARGIN / 2, 0.5]) == 0
    assert first_of_best([0.70, 0.70 + 2 * TIE_MARGIN, 0.5]) == 1


def test_the_screen_tries_every_third_rejection_value_and_the_last():
    assert list(SCREEN.sweep(UKR_SWEEP)) == [0.0, 1 / 8, 1.0, 8.0, 64.0]
    assert list(REFINE.sweep(UKR_SWEEP)) == list(UKR_SWEEP) == list(FULL.sweep(UKR_SWEEP))
    thresholds = np.r_[-np.inf, np.linspace(0, 1, 11), np.inf]
    assert SCREEN.sweep(thresholds)[0] == -np.inf and SCREEN.sweep(thresholds)[-1] == np.inf
    assert REFINE.models == FULL.models != SCREEN.models  # only the screen fits cheaper models


@pytest.mark.slow  # a whole evaluation (docs/testing.md)
def test_selection_screens_every_view_and_refines_the_best_third(three_recordings_npz):
    lines = []
    ev = RecordingsEvaluator(
        load_recordings(three_recordings_npz),
        methods=("ukr_clm",),
        quick=True,
        normalise=("training", "recording"),
        derived=("none", "velocities"),
        detail=lines.append,
    )
    fold = ev.run_fold("r0")
    screened = [line for line in lines if "ukr_clm screen" in line]
    refined = [line for line in lines if "ukr_clm refine" in line]
    assert len(screened) == 4 and len(refined) == 2
    chosen = fold.selected["ukr_clm"]
    view = f"'derived': '{chosen['derived']}', 'normalise': '{chosen['normalise']}'"
    assert any(view in line for line in refined)  # the choice is a refined candidate
    # the held-out recording is labelled by the full models, the screen's trained fewer steps
    train = ev.views("r0")[chosen["normalise"], chosen["derived"]][0]  # the fold's cache kept: its full fit
    full, cheap = (ev._fit(REGISTRY["ukr_clm"], train, chosen, f).model for f in (FULL, SCREEN))
    steps = [(len(full.models[c].model.history_), len(cheap.models[c].model.history_)) for c in full.models]
    assert all(f > c for f, c in steps), steps


@pytest.fixture(scope="module")
def evaluated(three_recordings_npz) -> tuple[RecordingsEvaluator, dict]:
    """An evaluation of a manifold method, its online replay and a score method (shared by the
    tests of its JSON: one evaluation per module and worker)."""
    ev = RecordingsEvaluator(
        load_recordings(three_recordings_npz), methods=("ukr_clm", "ukr_clm_online", "dtw_1nn"), quick=True
    )
    return ev, ev.evaluate()


@pytest.mark.slow  # a whole evaluation (docs/testing.md)
def test_the_json_reports_time_per_method_and_phase(evaluated):
    result = evaluated[1]
    timing = result["timing"]
    assert set(timing["methods"]["ukr_clm"]) == {"selection", "final_fit", "labelling"}
    assert set(timing["methods"]["ukr_clm_online"]) == {"labelling"}
    assert set(timing["folds"]) == set(result["parameters"]["recordings"])
    assert all(v > 0 for v in timing["methods"]["ukr_clm"].values())


def test_third_party_warnings_are_counted_not_printed(caplog):
    counts = Counter()
    with caplog.at_level(logging.WARNING), counted_warnings(counts):
        for current in (10239.7, 11716.6):
            logging.getLogger("hmmlearn.base").warning(
                "Model is not converging.  Current: %s is not greater than %s. Delta is -8e-05", current, current + 1
            )
        warnings.warn("overflow in exp", RuntimeWarning, stacklevel=1)
    assert not [r for r in caplog.records if r.name == "hmmlearn.base"]
    assert counts == {"hmmlearn.base: Model is not converging.": 2, "RuntimeWarning: overflow in exp": 1}
    assert summary(counts)[0] == "2 × hmmlearn.base: Model is not converging."
    logging.getLogger("hmmlearn.base").warning("after the block")
    assert [r.getMessage() for r in caplog.records if r.name == "hmmlearn.base"] == ["after the block"]


@pytest.mark.parametrize("bad", [{"methods": {"ukr_clm": {}}}, [], {"x": 1}])
def test_params_that_are_no_evaluation_result_say_so(bad):
    with pytest.raises(ValueError, match="not the --json output"):
        ChosenParameters(bad)


@pytest.mark.slow  # a whole evaluation (docs/testing.md)
def test_params_rerun_the_choices_with_the_labels_of_the_run_that_chose_them(evaluated, tmp_path):
    first, result = evaluated
    data, methods = first.data, first.methods
    assert methods == ("ukr_clm", "ukr_clm_online", "dtw_1nn")
    (tmp_path / "r.json").write_text(json.dumps(result))
    again = RecordingsEvaluator(data, methods=methods, quick=True, chosen=ChosenParameters.load(tmp_path / "r.json"))
    rerun = again.evaluate()
    for before, after in zip(first.folds_, again.folds_):
        for name in methods:
            np.testing.assert_array_equal(before.labels[name], after.labels[name])
    assert json.dumps(rerun["methods"]) == json.dumps(result["methods"])
    assert rerun["parameters"]["params_from"].endswith("r.json")
    with pytest.raises(ValueError, match=r"no parameters for \['hmm'\]"):
        RecordingsEvaluator(data, methods=("hmm",), chosen=ChosenParameters(result))


def _fold(recording: str, window: int, objective: float) -> dict:
    selected = {"window": window, "derived": "none", "normalise": "training", "reject": 0.5}
    return {
        "recording": recording,
        "selected": {**selected, "validation_objective": objective, "rejection": "calibrated"},
    }


def test_a_new_recording_gets_the_choice_of_most_folds_ties_to_the_first():
    folds = [_fold("a", 20, 0.7), _fold("b", 10, 0.6), _fold("c", 10, 0.65), _fold("d", 20, 0.9)]
    chosen = ChosenParameters({"methods": {"dtw_1nn": {"folds": folds}}})
    assert chosen.choice("dtw_1nn", "b").params["window"] == 10  # a held-out recording of that run: its own
    assert chosen.selected("dtw_1nn", "new")["window"] == 20  # 2 against 2: the first fold's
    assert chosen.choice("dtw_1nn", "new").params == {"window": 20, "derived": "none", "normalise": "training"}
    folds[3]["selected"]["window"] = 10
    assert chosen.__class__({"methods": {"dtw_1nn": {"folds": folds}}}).selected("dtw_1nn", "new")["window"] == 10


@pytest.mark.slow  # a whole evaluation (docs/testing.md)
def test_the_cache_gives_the_same_json_and_computes_only_a_method_added(three_recordings_npz, tmp_path, capsys):
    def run(methods: str, *extra: str) -> tuple[dict, str]:
        views = ["--normalise", "training", "--derived", "none"]  # one view: no screen of four
        argv = [str(three_recordings_npz), "--quick", "--json", "--jobs", "1", *views, "--methods", methods, *extra]
        assert run_command(register_evaluate, [*argv, "--cache", str(tmp_path / "cache")]) == 0
        out = capsys.readouterr()
        result = json.loads(out.out)
        result.pop("runtime_s"), result.pop("timing")
        return result, out.err

    first, err = run("ukr_clm,ukr_clm_online")
    assert "taken from" not in err
    again, err = run("ukr_clm,ukr_clm_online")
    assert again == first and err.count("ukr_clm taken from") == 3
    more, err = run("ukr_clm,ukr_clm_online,dtw_1nn")
    assert err.count("ukr_clm taken from") == 3 and "dtw_1nn taken from" not in err
    assert more["methods"]["ukr_clm"] == first["methods"]["ukr_clm"]
    # another setting: computed again (every method's key holds every setting, `_method_store`; dtw_1nn, cached by
    # the run above, is the cheap one to compute again)
    _, err = run("dtw_1nn")
    assert err.count("dtw_1nn taken from") == 3
    _, err = run("dtw_1nn", "--lag", "2")
    assert "taken from" not in err
