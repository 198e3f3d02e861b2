import numpy as np
import pytest
from sklearn.base import clone

from handflow.plugins.segmenter import CLMSegmenter, UKROnlyRecognizer
from handflow.plugins.segmenter.models import training_direction


def test_candidate_time_runs_forward_along_its_own_class(candidates, synthetic):
    a = next(t.data for t in synthetic.test if t.label == "A")
    proj = candidates.project(a)
    steps = np.sin(2 * np.diff(proj.latent_time[:, 0]))
    assert np.mean(steps > 0) > 0.9
    assert np.median(proj.errors[:, 0]) < np.median(proj.errors[:, 1:])


def test_training_direction_detects_a_reversed_time_axis():
    t = np.linspace(0, 3, 30)
    assert training_direction(t, np.zeros(30)) == 1.0
    assert training_direction(-t, np.zeros(30)) == -1.0


def test_ukr_only_stream_equals_batch(candidates, two_letters):
    Y, truth = two_letters
    rec = UKROnlyRecognizer(candidates, history=10, threshold=-0.5)
    batch = rec.predict(Y)
    C_batch = rec.compatibilities_projected(candidates.project(Y))
    rec.reset()
    stream = [rec.update(y) for y in Y]
    np.testing.assert_array_equal([s[0] for s in stream], batch)
    # single-point and batch projections agree to the projection tolerance
    np.testing.assert_allclose(np.array([s[1] for s in stream]), C_batch, atol=1e-6)
    assert np.mean(batch == truth) > 0.8


def test_ukr_only_validates_parameters_at_first_use(candidates, two_letters):
    Y, _ = two_letters
    bad = UKROnlyRecognizer(candidates, order_rating="tan")  # the constructor only stores
    with pytest.raises(ValueError, match="order rating"):
        bad.predict(Y[:5])
    with pytest.raises(ValueError, match="lambda"):
        UKROnlyRecognizer(candidates, lam=2.0).update(Y[0])
    assert clone(UKROnlyRecognizer(candidates, history=5)).get_params()["history"] == 5


def test_clm_segments_two_concatenated_letters(candidates, two_letters):
    Y, truth = two_letters
    seg = CLMSegmenter(candidates, history=10, random_state=0)
    labels = seg.fit_predict(Y)
    assert seg.converged_ and 1 <= seg.n_sweeps_ < 1000
    assert np.isfinite(seg.energy_) and seg.energy_ < 0
    assert np.mean(labels == truth) > 0.9


def test_strong_background_rejects_a_reversed_letter(candidates, synthetic):
    a = next(t.data for t in synthetic.test if t.label == "A")
    weak = CLMSegmenter(candidates, history=10, background_factor=1.0, random_state=0)
    assert np.mean(weak.fit_predict(a) == 0) > 0.9  # the forward letter is accepted …
    strong = CLMSegmenter(candidates, history=10, background_factor=3.0, random_state=0)
    assert np.mean(strong.fit_predict(a[::-1]) == -1) > 0.9  # … its reversal is rejected


SEGMENT_RULES = [{"min_progress": 0.3}, {"max_fit_ratio": 2.0}]


@pytest.mark.parametrize("rule", SEGMENT_RULES)
def test_a_segment_rule_rejects_a_reversed_letter_and_keeps_the_forward_one(candidates, synthetic, rule):
    a = next(t.data for t in synthetic.test if t.label == "A")
    # a weak background: the reversal is matched piece by piece by forward arcs of the candidates
    plain = CLMSegmenter(candidates, history=10, background_factor=0.5, random_state=0)
    strict = CLMSegmenter(candidates, history=10, background_factor=0.5, random_state=0, **rule)
    assert np.mean(strict.fit_predict(a) == 0) > 0.9
    reversed_plain = np.mean(plain.fit_predict(a[::-1]) == -1)
    reversed_strict = np.mean(strict.fit_predict(a[::-1]) == -1)
    assert reversed_plain < 0.8 and reversed_strict > 0.9
    np.testing.assert_array_equal(strict.labels_, strict.fit_predict(a[::-1]))


@pytest.mark.parametrize("bad", [{"min_progress": -1}, {"max_fit_ratio": 0.5}])
def test_segment_rules_refuse_impossible_values(candidates, synthetic, bad):
    a = next(t.data for t in synthetic.test if t.label == "A")
    with pytest.raises(ValueError, match=next(iter(bad))):
        CLMSegmenter(candidates, **bad).fit_predict(a)


@pytest.mark.parametrize("rule", SEGMENT_RULES)
def test_an_online_segment_rule_rejects_the_reversal_as_the_batch_does(candidates, synthetic, rule):
    from handflow.plugins.segmenter import OnlineCLMSegmenter

    a = next(t.data for t in synthetic.test if t.label == "A")
    Y = np.vstack([a, a[::-1], a])  # forward, reversed, forward: the middle letter must be rejected
    params = dict(history=10, background_factor=0.5, random_state=0)
    batch = CLMSegmenter(candidates, **params, **rule).fit_predict(Y)
    online = OnlineCLMSegmenter(candidates, window=120, **params, **rule).replay(Y)
    n = len(a)
    # the reversal's first and last few observations join the forward letters next to them
    assert np.mean(online[n : 2 * n] == -1) > 0.8 and np.mean(online[:n] == 0) > 0.9
    assert np.mean(online == batch) > 0.98
    plain = OnlineCLMSegmenter(candidates, window=120, **params).replay(Y)
    assert np.mean(plain[n : 2 * n] == -1) < 0.6


def test_the_score_segmenter_refuses_the_segment_rules():
    from handflow.plugins.segmenter.online import OnlineScoreCLMSegmenter
    from handflow.plugins.segmenter.scorers import DTWScorer

    rng = np.random.default_rng(0)
    scorer = DTWScorer(window=5).fit({"a": [rng.normal(size=(30, 2))], "b": [rng.normal(size=(30, 2))]})
    with pytest.raises(ValueError, match="min_progress and max_fit_ratio need class manifolds' latent time"):
        OnlineScoreCLMSegmenter(scorer, min_progress=0.3)
    with pytest.raises(ValueError, match="max_fit_ratio need"):
        OnlineScoreCLMSegmenter(scorer, max_fit_ratio=2.0)


def test_clm_is_reproducible_with_a_seed(candidates, two_letters):
    Y, _ = two_letters
    a = CLMSegmenter(candidates, random_state=4).fit_predict(Y)
    b = CLMSegmenter(candidates, random_state=4).fit_predict(Y)
    np.testing.assert_array_equal(a, b)


def test_nan_observations_get_a_clear_error(candidates, two_letters):
    Y = two_letters[0].copy()
    Y[3, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        CLMSegmenter(candidates).fit_predict(Y)


def test_training_rejects_an_unknown_init(synthetic):
    from handflow.plugins.segmenter import train_class_models

    with pytest.raises(ValueError, match="init must be one of"):
        train_class_models(synthetic, n_steps=0, init="tsne")


def test_equidistant_init_spreads_each_class_over_the_period(ukr_models):
    for model in ukr_models.values():
        lt = np.mod(model.latents_[:, 0], np.pi)
        # the trained time axis still covers most of the period (no collapse onto a short arc)
        occupied = np.unique(np.floor(lt / (np.pi / 8))).size
        assert occupied >= 6
