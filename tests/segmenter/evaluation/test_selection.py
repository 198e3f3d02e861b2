import pytest

from handflow.plugins.segmenter.evaluation import Evaluator, TrajectoryProtocol


def _results(recognition: float, rejection: float | None) -> dict:
    res = {e: {"mean_correct": recognition} for e in ("single", "concatenated", "middle_halves")}
    res.update({e: {"mean_correct": rejection} for e in ("reversed_rejection", "left_out_rejection")})
    return res


def test_open_set_selection_weighs_keeping_and_rejecting_alike(synthetic, candidates):
    ev = Evaluator(synthetic, candidates, TrajectoryProtocol.quick())
    assert ev.objective(_results(0.8, 0.4)) == pytest.approx(0.6)
    # keeping every motion and rejecting none scores below a point that does some of both
    assert ev.objective(_results(0.9, 0.0)) < ev.objective(_results(0.75, 0.6))
    assert ev.objective(_results(0.8, None)) == pytest.approx(0.8)  # no rejection experiment: recognition alone


def test_recognition_selection_ignores_the_rejection_experiments(synthetic, candidates):
    ev = Evaluator(synthetic, candidates, TrajectoryProtocol(selection="recognition"))
    assert ev.objective(_results(0.9, 0.0)) == pytest.approx(0.9)
    with pytest.raises(ValueError, match="selection must be one of"):
        TrajectoryProtocol(selection="both")


@pytest.mark.parametrize("rule", [{"min_progress": 0.3}, {"max_fit_ratio": 1.0}])
def test_segment_rules_are_selected_with_the_clm_parameters(synthetic, candidates, rule):
    ev = Evaluator(synthetic, candidates, TrajectoryProtocol.quick())
    grid = ev.grid("ukr_clm")
    assert {p["min_progress"] for p in grid} == {0.0, 0.3} and {p["min_span"] for p in grid} == {0, 20}
    assert {p["max_fit_ratio"] for p in grid} == {None, 2.0}
    case = next(c for c in ev.cases["validation"] if c.experiment == "reversed_rejection")
    params = {"background_factor": 0.5, "error_scale": 1.0}
    plain = ev.predict("ukr_clm", params, "validation", case)
    strict = ev.predict("ukr_clm", dict(params, **rule), "validation", case)
    assert len(ev._labels) == 1  # the rules judge the same CLM labels
    assert (strict == -1).sum() > (plain == -1).sum()
    assert ((strict == plain) | (strict == -1)).all()  # a segment rule only ever rejects
