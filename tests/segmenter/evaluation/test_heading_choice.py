"""The thesis protocol's validation split chooses the heading channels of the manifold methods
(docs/segmentation.md, heading channels); ``--headings`` given overrides the choice."""

import json

import pytest

from handflow.plugins.segmenter import candidate_set
from handflow.plugins.segmenter.cli import register_evaluate
from handflow.plugins.segmenter.evaluation import Evaluator, TrajectoryProtocol, heading_choices
from handflow.plugins.segmenter.models import fit_class_models
from tests.conftest import run_command
from tests.segmenter.datasets.test_trajectories import write_csv_dataset


def _candidates(synthetic, headings: tuple[int, ...], spoiled: bool):
    """Candidates with those heading channels; ``spoiled``: every class's manifold trained on the next
    class's samples, so that the candidate set labels every letter wrong on validation."""
    by_class = synthetic.by_class("train")
    labels = sorted(by_class)
    data = {c: by_class[labels[(k + spoiled) % len(labels)]] for k, c in enumerate(labels)}
    return candidate_set(fit_class_models(data, n_steps=40, random_state=0, headings=headings))


def test_the_candidate_rule_offers_the_position_pair_with_two_channels_or_more():
    # the documented preference first: a tie keeps the heading channels
    assert heading_choices(3) == ((0, 1), ()) and heading_choices(2) == ((0, 1), ())
    assert heading_choices(1) == ((),)


@pytest.mark.parametrize("headings_win", [True, False])
def test_validation_chooses_the_candidate_set_that_scores_best(synthetic, headings_win):
    plain = _candidates(synthetic, (), spoiled=headings_win)
    headed = _candidates(synthetic, (0, 1), spoiled=not headings_win)
    said = []
    ev = Evaluator(synthetic, plain, TrajectoryProtocol.quick(), progress=said.append, alternatives=(headed,))
    out = ev.evaluate(("ukr_only", "dtw_1nn"))
    chosen = [0, 1] if headings_win else []
    assert out["parameters"]["heading_candidates"] == [[], [0, 1]]
    assert out["parameters"]["heading_channels"] == {"ukr_only": chosen}  # the baselines have no manifolds
    assert ev.chosen["ukr_only"].headings == chosen
    assert any(f"validation chose heading channels {chosen or 'none'}" in m for m in said)
    assert out["methods"]["ukr_only"]["single"]["mean_correct"] > 0.5  # tested with the chosen candidates


@pytest.mark.slow  # a whole evaluation (docs/testing.md)
def test_headings_given_are_not_chosen_and_none_can_be_forced(tmp_path, synthetic, capsys):
    data = str(write_csv_dataset(tmp_path / "letters", synthetic))
    argv = ["--methods", "ukr_only", "--quick", "--json", "--steps", "20"]
    for option, candidates, reported in (
        ([], [[0, 1], []], "validation"),
        (["--headings", "x,y"], [[0, 1]], "x,y"),
        (["--headings", "none"], [[]], "none"),
    ):
        assert run_command(register_evaluate, [data, *argv, *option]) == 0
        out, err = capsys.readouterr()
        parameters = json.loads(out)["parameters"]
        assert parameters["heading_candidates"] == candidates and parameters["headings"] == reported
        assert parameters["heading_channels"]["ukr_only"] in candidates
        assert ("validation chose heading channels" in err) == (not option)
