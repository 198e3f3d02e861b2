import numpy as np
import pytest

from handflow.plugins.segmenter.compatibility import (
    background_band,
    candidate_band,
    history_compatibility,
    order_rating_cos,
    order_rating_sign,
    pair_error_max,
    pair_error_mean,
    reconstruction_compatibility,
    reject_small_progress,
    thesis_background_strength,
)


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
