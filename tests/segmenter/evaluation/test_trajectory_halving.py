"""The trajectory protocol's selection (docs/segmentation.md, "How the trajectory protocol
chooses"): successive halving over each method's grid, the heading channels chosen over
cross-fitted splits with the tie rule of ``_selection``, and the work shared between cases."""

import math

import numpy as np
import pytest

from handflow.plugins.segmenter import LetterGenerator, candidate_set
from handflow.plugins.segmenter.clm import CLMSegmenter
from handflow.plugins.segmenter.datasets import LabelledDataset
from handflow.plugins.segmenter.evaluation import SEGMENT_RULES, Evaluator, TrajectoryProtocol, heading_choices
from handflow.plugins.segmenter.evaluation._fidelity import NESTED
from handflow.plugins.segmenter.evaluation._selection import TIE_MARGIN, first_of_best
from handflow.plugins.segmenter.evaluation._trajectory_cases import cross_fitted_splits, screen_pairs
from handflow.plugins.segmenter.models import train_class_models

PROTOCOL = TrajectoryProtocol(nths=(1, 2), histories=(5, 20), runs=2, max_pairs=4)


@pytest.fixture(scope="module")
def letters():
    """Four synthetic letter classes, 3 train / 1 validation / 2 test samples each."""
    return LetterGenerator(n_classes=4, random_state=1, noise=0.01).dataset((3, 1, 2))


def train(ds: LabelledDataset, headings: tuple[int, ...]):
    return candidate_set(train_class_models(ds, n_steps=40, random_state=0, headings=headings))


@pytest.fixture(scope="module")
def plain(letters):
    return train(letters, ())


def test_the_screen_is_the_diagonal_of_the_design_and_covers_every_nth_and_history():
    assert screen_pairs(TrajectoryProtocol()) == {(1, 5), (2, 10), (3, 15), (4, 20)}
    assert screen_pairs(PROTOCOL) == {(1, 5), (2, 20)}
    assert screen_pairs(TrajectoryProtocol(nths=(1, 2), histories=(10,))) == {(1, 10), (2, 10)}


def test_halving_screens_every_grid_point_and_refines_the_best_third(letters, plain, monkeypatch):
    ev = Evaluator(letters, plain, PROTOCOL)
    grid = ev.grid("ukr_only")
    rng = np.random.default_rng(0)
    screen = {repr(sorted(p.items())): float(v) for p, v in zip(grid, rng.uniform(0.2, 0.8, len(grid)))}
    asked = []

    def fake(method, params, screen_only=False):
        asked.append((repr(sorted(params.items())), screen_only))
        value = screen[repr(sorted(params.items()))]
        return value if screen_only else value - 0.1  # the refined objective: a constant shift

    monkeypatch.setattr(ev, "validation_objective", lambda m, p, screen=False: fake(m, p, screen))
    params, score = ev.select("ukr_only")
    n_keep = math.ceil(len(grid) * NESTED.keep)
    best_third = sorted(screen.values(), reverse=True)[:n_keep]
    refined = [key for key, screened in asked if not screened]
    assert sum(screened for _, screened in asked) == len(grid)  # every grid point screened once
    assert len(refined) == n_keep and sorted((screen[k] for k in refined), reverse=True) == best_third
    assert score == pytest.approx(max(screen.values()) - 0.1) and screen[repr(sorted(params.items()))] == max(
        screen.values()
    )


def test_within_the_tie_margin_the_first_grid_point_wins(letters, plain, monkeypatch):
    ev = Evaluator(letters, plain, PROTOCOL)
    grid = ev.grid("ukr_only")
    values = {repr(sorted(p.items())): 0.5 for p in grid}
    values[repr(sorted(grid[-1].items()))] = 0.5 + TIE_MARGIN / 2  # best, but within the margin of the first
    monkeypatch.setattr(ev, "validation_objective", lambda m, p, screen=False: values[repr(sorted(p.items()))])
    assert ev.select("ukr_only")[0] == grid[0]
    values[repr(sorted(grid[-1].items()))] = 0.5 + 3 * TIE_MARGIN  # a clear margin
    ev._objectives.clear()
    assert ev.select("ukr_only")[0] == grid[-1]


def test_halving_chooses_what_an_exhaustive_search_chooses(letters, plain):
    ev = Evaluator(letters, plain, PROTOCOL)
    params, score = ev.select("ukr_only")
    grid = ev.grid("ukr_only")
    exhaustive = [ev.objective(ev.run("ukr_only", p, "validation")) for p in grid]
    assert params == grid[first_of_best(exhaustive)] and score == pytest.approx(exhaustive[first_of_best(exhaustive)])
    refined = [k for k in ev._objectives if not k[2]]
    assert len(refined) == math.ceil(len(grid) * NESTED.keep)  # only the best third ran on every case


def test_cross_fitted_splits_validate_every_train_and_validation_trajectory_once(letters):
    folds = cross_fitted_splits(letters)
    assert len(folds) == 4 and folds[0] is letters
    names = lambda ts: sorted(t.name for t in ts)  # noqa: E731
    assert sorted(n for f in folds for n in names(f.validation)) == names(letters.train + letters.validation)
    for f in folds:
        assert len(f.train) == len(letters.train) and names(f.test) == names(letters.test)
        assert not set(names(f.train)) & set(names(f.validation))
        assert {t.label for t in f.validation} == set(letters.classes)  # one per class
    assert len(cross_fitted_splits(letters, folds=2)) == 2


def _headed_choice(letters, plain, validation_order=None):
    ds = (
        letters
        if validation_order is None
        else LabelledDataset(
            letters.train, [letters.validation[i] for i in validation_order], letters.test, letters.columns
        )
    )
    headed = train(ds, (0, 1))
    ev = Evaluator(ds, headed, PROTOCOL, alternatives=(plain,), trainer=train)  # heading_choices' order
    ev.choose("ukr_only")
    return ev


@pytest.mark.slow  # a whole evaluation (docs/testing.md)
def test_the_heading_choice_is_made_on_every_split_and_does_not_flip_under_a_permutation(letters, plain):
    ev = _headed_choice(letters, plain)
    record = ev.choices["ukr_only"]["headings"]
    assert [r["channels"] for r in record] == [list(h) for h in heading_choices(2)]  # the preference first
    assert all(len(r["folds"]) == 4 for r in record)  # decided on the 4 cross-fitted splits
    assert all(r["pooled"] == pytest.approx(np.mean(r["folds"])) for r in record)
    assert record[0]["folds"][0] == pytest.approx(ev.validation_objective("ukr_only", record[0]["params"], True))
    pooled = [r["pooled"] for r in record]
    chosen = first_of_best(pooled)
    assert ev.chosen["ukr_only"].headings == record[chosen]["channels"]
    permuted = _headed_choice(letters, plain, validation_order=np.random.default_rng(3).permutation(4))
    again = permuted.choices["ukr_only"]["headings"]
    assert permuted.chosen["ukr_only"].headings == ev.chosen["ukr_only"].headings
    assert [r["pooled"] for r in again] == pytest.approx(pooled)


def test_a_tie_of_the_pooled_heading_objectives_keeps_the_first_candidate_set(letters, plain, monkeypatch):
    headed = train(letters, (0, 1))
    ev = Evaluator(letters, headed, PROTOCOL, alternatives=(plain,), trainer=train)  # heading_choices' order
    for gain, chosen in ((TIE_MARGIN / 2, [0, 1]), (3 * TIE_MARGIN, [])):
        # the second candidate set (no heading channels) scores ``gain`` more on every split
        def pooled(tasks, gain=gain):
            return [[[0.6 + h * gain] * 4 for _ in t] for h, t in enumerate(tasks)]

        monkeypatch.setattr(ev, "cross_fit", pooled)
        ev.choose("ukr_only")
        assert ev.chosen["ukr_only"].headings == chosen


def test_cases_that_differ_only_in_h_share_the_clm_run_where_the_span_is_the_same(letters, plain):
    ev = Evaluator(letters, plain, PROTOCOL)
    single = [c for c in ev.cases["validation"] if c.experiment == "single" and c.nth == 1]
    a, b = (next(c for c in single if c.history == h and c.name == single[0].name) for h in (5, 20))
    assert a.draw == b.draw
    spanned = {"background_factor": 1.0, "error_scale": 1.0, "min_span": 20}
    la, lb = (ev.predict("ukr_clm", spanned, "validation", c, seed=a.draw) for c in (a, b))
    assert len(ev._labels) == 1 and (la == lb).all()
    ev.predict("ukr_clm", dict(spanned, min_span=0), "validation", a, seed=a.draw)  # span 5: a run of its own
    assert len(ev._labels) == 2
    # the shared bands give the segmenter's own labels
    proj = ev.projection("validation", a)
    own = CLMSegmenter(plain, history=5, min_span=0, random_state=a.draw).fit_predict_projected(proj)
    assert (ev.clm_labels("validation", a, a.draw, plain, proj, {"min_span": 0}) == own).all()


def test_baseline_scores_of_a_concatenation_equal_those_of_the_joined_sequence(letters, plain):
    ev = Evaluator(letters, plain, PROTOCOL)
    case = next(c for c in ev.cases["validation"] if c.experiment == "concatenated" and c.history == 5)
    model = ev.dtw
    model.window = case.history
    whole = model.scores(ev.sequence("validation", case))
    assert np.allclose(ev.baseline_scores("dtw_1nn", "validation", case), whole)


@pytest.mark.slow  # a whole evaluation (docs/testing.md)
def test_forked_processes_give_the_same_figures(letters, plain):
    headed = train(letters, (0, 1))
    outs = []
    for jobs in (1, 2):
        ev = Evaluator(letters, headed, PROTOCOL, alternatives=(plain,), trainer=train, jobs=jobs)
        out = ev.evaluate(("ukr_only", "dtw_1nn"))
        out["parameters"].pop("timing_s")
        outs.append(out)
    assert outs[0] == outs[1]


def test_grid_points_sharing_a_clm_run_are_screened_and_refined_together(letters, plain, monkeypatch):
    ev = Evaluator(letters, plain, PROTOCOL)
    grid = ev.grid("ukr_clm")
    run_of = lambda p: repr(sorted((k, v) for k, v in p.items() if k not in SEGMENT_RULES))  # noqa: E731
    runs = sorted({run_of(p) for p in grid})
    rng = np.random.default_rng(1)
    value = {repr(sorted(p.items())): float(v) for p, v in zip(grid, rng.uniform(0.2, 0.8, len(grid)))}
    refined = []

    def fake(method, params, screen=False):
        if not screen:
            refined.append(run_of(params))
        return value[repr(sorted(params.items()))]

    monkeypatch.setattr(ev, "validation_objective", fake)
    params, _ = ev.select("ukr_clm")
    best_of_run = {r: max(value[repr(sorted(p.items()))] for p in grid if run_of(p) == r) for r in runs}
    kept = sorted(runs, key=lambda r: -best_of_run[r])[: math.ceil(len(runs) * NESTED.keep)]
    assert sorted(set(refined)) == sorted(kept)  # the best third of the runs, by their best rule
    assert len(refined) == len(kept) * len(grid) // len(runs)  # each with all its segment rules
    assert ev._halving == {"candidates": 112, "runs": 28, "refined_runs": len(kept), "refined": len(refined)}
