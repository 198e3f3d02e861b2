import numpy as np
import pytest

from handflow.plugins.segmenter.compatibility import (
    background_band,
    bridged_latent,
    candidate_band,
    history_compatibility,
    null_class_evidence,
    order_rating_cos,
    order_rating_sign,
    pair_error_max,
    pair_error_mean,
    reconstruction_compatibility,
    reject_poor_fit,
    reject_segments,
    reject_small_progress,
    thesis_background_strength,
    unwrapped_latent,
)
from handflow.plugins.segmenter.evaluation._metrics import score_thresholds, threshold_labels


def test_forward_step_is_plus_one_backward_minus_one():
    assert order_rating_cos(np.array(0.01)) == pytest.approx(1.0, abs=1e-3)
    assert order_rating_cos(np.array(-0.01)) == pytest.approx(-1.0, abs=1e-3)
    assert order_rating_cos(np.array(np.pi / 2)) == pytest.approx(0.0, abs=1e-12)
    assert order_rating_sign(np.array([0.3, -0.3])).tolist() == [1.0, -1.0]


def test_wrap_around_forward_step_counts_as_forward():
    # from just below π to just above 0 is a small forward step on the period-π time axis
    delta = np.array(0.02) - np.array(np.pi - 0.02)
    assert order_rating_cos(delta) == pytest.approx(np.cos(0.04))
    assert order_rating_sign(delta) == 1.0
    assert order_rating_sign(np.array(np.pi - 0.02) - np.array(0.02)) == -1.0


def test_reconstruction_compatibility_range():
    c = reconstruction_compatibility(np.array([0.0, np.log(2), 1e6]))
    np.testing.assert_allclose(c, [1.0, 0.0, -1.0], atol=1e-12)


def test_history_counts_current_observation_as_h1():
    c = np.array([[1.0], [0.0], [0.0]])
    his = history_compatibility(c, history=2, gamma=0.5)
    # t=0: only itself; t=1: (0.5·0 + 0.25·1)/0.75; t=2: lag 2 is outside H=2
    np.testing.assert_allclose(his[:, 0], [1.0, 1 / 3, 0.0])


def test_candidate_band_on_a_handmade_sequence():
    lt = np.array([[0.0, 0.3], [0.1, 0.2], [0.2, 0.1]])  # candidate 0 forward, candidate 1 backward
    e = np.array([[0.0, 0.0], [0.0, 0.0], [np.log(2) * 3, 0.0]])
    band = candidate_band(lt, e, width=2)
    assert band[0, 0, 0] == pytest.approx(1.0)  # forward, perfect fit
    assert band[1, 0, 0] == pytest.approx(0.0)  # backward: ½(−1 + 1)
    # pair (0, 2): mean error over 0…2 is log 2 → c_sre = 0 → f = ½(1 + 0)
    assert band[0, 0, 1] == pytest.approx(0.5)
    assert band[0, 2].tolist() == [0.0, 0.0]  # no partner past the end


def test_pair_error_mean_uses_the_whole_neighbourhood():
    e = np.array([[1.0], [2.0], [6.0]])
    out = pair_error_mean(e, 2)
    assert out[0, 0, 1] == pytest.approx(3.0) and out[0, 1, 0] == pytest.approx(4.0)


def test_background_band_decays_and_self_excites():
    band, diag = background_band(5, 3, strength=0.8, radius=3)
    assert diag == 0.8
    np.testing.assert_allclose(band[0], [0.8 * 2 / 3, 0.8 / 3, 0.0])
    assert band[4].tolist() == [0.0, 0.0, 0.0]
    assert thesis_background_strength(100) == pytest.approx(0.9)


def test_unwrapped_path_rates_long_forward_spans_forward():
    lt = np.mod(np.linspace(0.0, 0.8 * np.pi, 9), np.pi)[:, None]  # steady forward, 0.1π per step
    e = np.zeros_like(lt)
    direct = candidate_band(lt, e, width=8, order_path="direct")
    unwrapped = candidate_band(lt, e, width=8, order_path="unwrapped")
    assert direct[0, 0, 7] == pytest.approx(0.0)  # 0.8π apart: the direct sign rating calls it backward
    assert np.all(unwrapped[0, 0] == 1.0)
    back = candidate_band(lt[::-1], e, width=8, order_path="unwrapped")
    assert np.all(back[0, 0] == 0.0)  # backward: ½(−1 + 1)


def test_seam_of_an_open_stroke_breaks_pairs_across_a_restart():
    # one stroke running 0 → π, then a new stroke from 0: forward on the periodic axis, but a restart
    lt = np.r_[np.linspace(0.05, 3.05, 7), np.linspace(0.05, 1.0, 4)][:, None]
    e = np.zeros_like(lt)
    periodic = candidate_band(lt, e, width=3, order_path="unwrapped", seams=np.array([np.nan]))
    stroke = candidate_band(lt, e, width=3, order_path="unwrapped", seams=np.array([3.1]))
    assert np.all(periodic[0, 4:7][periodic[0, 4:7] != 0] == 1.0)  # a repetition continues
    assert stroke[0, 6, 0] == 0.0 and stroke[0, 5, 1] == 0.0  # pairs across the seam: ½(−1 + 1)
    assert stroke[0, 2, 0] == 1.0 and stroke[0, 7, 0] == 1.0  # within each stroke: forward


def test_pair_error_max_is_the_worst_observation_between():
    e = np.array([[1.0], [5.0], [2.0], [0.5]])
    out = pair_error_max(e, 3)
    assert out[0, 0].tolist() == [5.0, 5.0, 5.0] and out[0, 2, 0] == 2.0 and np.isnan(out[0, 3, 0])


def test_segments_with_too_little_latent_progress_are_rejected():
    # candidate 0 advances 0.05π per step, candidate 1 0.01π, candidate 2 runs backwards
    steps = np.tile([0.05, 0.01, -0.05], (30, 1)) * np.pi
    lt = np.mod(np.cumsum(steps, axis=0), np.pi)
    labels = np.r_[np.zeros(10), np.ones(10), np.full(5, 2), np.full(5, -1)].astype(int)
    out = reject_small_progress(labels, lt, 0.3)
    # 9 steps of 0.05 = 0.45 periods kept; 0.09 periods and backward progress rejected
    np.testing.assert_array_equal(out, np.r_[np.zeros(10), np.full(20, -1)])
    np.testing.assert_array_equal(reject_small_progress(labels, lt, 0.0), labels)
    assert reject_small_progress(labels, lt, 0.5)[:10].tolist() == [-1] * 10
    with pytest.raises(ValueError, match="min_progress"):
        reject_small_progress(labels, lt, -0.1)


def test_a_projection_spike_is_bridged_and_adds_no_progress():
    lt = np.mod(np.linspace(0.0, 0.6 * np.pi, 13), np.pi)[:, None]  # steady forward, 0.05π per step
    spiked = lt.copy()
    spiked[6] = np.mod(lt[6] + 0.5 * np.pi, np.pi)  # one observation projected onto another branch
    np.testing.assert_allclose(bridged_latent(spiked), lt, atol=1e-12)
    assert unwrapped_latent(spiked)[-1, 0] == pytest.approx(0.6 * np.pi)
    band = candidate_band(spiked, np.zeros_like(lt), width=4, order_path="unwrapped")
    assert np.all(band[0, :9] == 1.0)  # every pair, across the spike too, is rated forward
    labels = np.zeros(13, dtype=int)
    assert reject_small_progress(labels, spiked, 0.3).tolist() == labels.tolist()


def test_only_a_jump_out_and_back_is_a_spike():
    fast = np.array([[0.0], [0.1], [0.95], [1.05]])  # a fast move: 0.85 forward, then on from there
    np.testing.assert_array_equal(bridged_latent(fast), fast)
    ends = np.array([[1.6], [0.1], [0.2], [0.3], [0.4], [1.9]])  # the first and the last have one neighbour
    np.testing.assert_array_equal(bridged_latent(ends), ends)
    apart = np.array([[0.0], [1.5], [0.9]])  # the neighbours lie 0.9 apart: no spike between them
    np.testing.assert_array_equal(bridged_latent(apart), apart)


def test_a_two_observation_spike_is_bridged_a_longer_excursion_is_not():
    lt = np.linspace(0.1, 0.5, 9)[:, None]
    two = lt.copy()
    two[3:5] = 2.0
    np.testing.assert_allclose(bridged_latent(two), lt, atol=1e-12)
    three = lt.copy()
    three[3:6] = 2.0  # three observations on another branch: taken as they are
    np.testing.assert_array_equal(bridged_latent(three), three)


def test_segments_their_candidate_fits_worse_than_another_are_rejected():
    # candidate 0 fits the first segment best; on the second, labelled 1, candidate 0 fits 3× better
    errors = np.array([[0.1, 0.3]] * 4 + [[0.1, 0.3]] * 4 + [[0.2, 0.25]] * 3)
    labels = np.r_[np.zeros(4), np.ones(4), np.ones(3) * 0].astype(int)
    np.testing.assert_array_equal(reject_poor_fit(labels, errors, 2.0), np.r_[np.zeros(4), np.full(4, -1), np.zeros(3)])
    np.testing.assert_array_equal(reject_poor_fit(labels, errors, 3.5), labels)
    np.testing.assert_array_equal(reject_poor_fit(labels, errors, None), labels)
    with pytest.raises(ValueError, match="max_fit_ratio"):
        reject_poor_fit(labels, errors, 0.9)
    # both rules: a segment the fit rule rejects is not judged by its progress
    lt = np.tile(np.linspace(0.0, 0.5 * np.pi, 11)[:, None], (1, 2))
    np.testing.assert_array_equal(
        reject_segments(labels, lt, errors, 0.1, 2.0), np.r_[np.zeros(4), np.full(4, -1), np.zeros(3)]
    )


def test_segments_at_an_open_end_are_not_judged():
    errors = np.array([[0.1, 0.3]] * 6)
    labels = np.array([1, 1, 0, 0, 1, 1])  # both 1-segments fit 3× worse than candidate 0
    lt = np.zeros((6, 2))
    assert reject_segments(labels, lt, errors, 0.0, 2.0).tolist() == [-1, -1, 0, 0, -1, -1]
    assert reject_segments(labels, lt, errors, 0.0, 2.0, open_ends=(True, False)).tolist() == [1, 1, 0, 0, -1, -1]
    assert reject_segments(labels, lt, errors, 0.0, 2.0, open_ends=(False, True)).tolist() == [-1, -1, 0, 0, 1, 1]


def test_the_null_class_wins_exactly_where_the_classifier_rejects_at_its_threshold():
    """Per frame, the argmax of the evidence with a null class scoring the threshold is the
    classifier's own decision with rejection at that threshold (docs/segmentation.md)."""
    scores = np.random.default_rng(0).normal(size=(200, 4))
    for threshold in score_thresholds(scores.max(axis=1), 11):
        evidence = null_class_evidence(scores, threshold)
        assert evidence.shape == (200, 5) and np.allclose(evidence.sum(axis=1), 1)
        decision = np.where(evidence.argmax(axis=1) == 4, -1, evidence.argmax(axis=1))
        assert np.array_equal(decision, threshold_labels(scores, threshold))
    assert np.all(null_class_evidence(scores, -np.inf)[:, 4] == 0)  # no null class: no rejection
    assert np.all(null_class_evidence(scores, np.inf)[:, 4] == 1)  # everything rejected
