"""Swap counter on hand-made ball trajectories (handflow.plugins.simulator.metrics)."""

import numpy as np
import pytest

from handflow.plugins.simulator.metrics import count_swaps, pair_rotation, swap_progress, swap_times, swaps_per_minute


def _circling(angles, centre=(0.0, 0.07), radius=0.02):
    """Two balls diametrically opposite on a circle, the pair at ``angles`` (rad)."""
    d = radius * np.c_[np.cos(angles), np.sin(angles)]
    return np.asarray(centre) + d, np.asarray(centre) - d


def test_each_half_revolution_is_one_swap_in_either_direction():
    p1, p2 = _circling(np.linspace(0, 3.2 * np.pi, 200))
    assert count_swaps(p1, p2) == 3
    np.testing.assert_allclose(swap_progress(p1, p2)[-1], 3.2)
    q1, q2 = _circling(np.linspace(0, -2.1 * np.pi, 200))
    assert count_swaps(q1, q2) == 2 and count_swaps(q1, q2, direction=1) == 0


def test_back_and_forth_motion_counts_nothing():
    p1, p2 = _circling(0.9 * np.pi * np.sin(np.linspace(0, 6 * np.pi, 300)))
    assert count_swaps(p1, p2) == 0


def test_a_swap_undone_by_turning_back_is_not_counted():
    p1, p2 = _circling(np.r_[np.linspace(0, 1.2 * np.pi, 100), np.linspace(1.2 * np.pi, 0.5 * np.pi, 50)])
    assert count_swaps(p1, p2) == 0


def test_exchanged_ball_labels_do_not_change_the_count():
    p1, p2 = _circling(np.linspace(0, 2.5 * np.pi, 200))
    a, b = p1.copy(), p2.copy()
    a[80:], b[80:] = p2[80:], p1[80:]  # the tracker swapped the identities of the identical balls
    assert count_swaps(a, b) == count_swaps(p1, p2) == 2
    np.testing.assert_allclose(pair_rotation(a, b), pair_rotation(p1, p2), atol=1e-12)


def test_missing_balls_are_skipped_and_reported_as_nan():
    p1, p2 = _circling(np.linspace(0, 2.2 * np.pi, 100))
    p1[[10, 11, 50]] = np.nan
    progress = swap_progress(p1, p2)
    assert np.isnan(progress[[10, 11, 50]]).all() and count_swaps(p1, p2) == 2


def test_swap_times_and_rate():
    t = np.linspace(0.0, 60.0, 601)
    p1, p2 = _circling(np.pi * t / 10.0)  # one swap every 10 s
    np.testing.assert_allclose(swap_times(t, p1, p2), [10, 20, 30, 40, 50, 60], atol=0.11)
    assert swaps_per_minute(t, p1, p2) == pytest.approx(6.0)


def test_bad_input_is_rejected_with_a_clear_message():
    with pytest.raises(ValueError, match=r"\(n, 2\)"):
        count_swaps(np.zeros((5, 3)), np.zeros((5, 3)))
    with pytest.raises(ValueError, match="direction"):
        count_swaps(np.zeros((5, 2)), np.ones((5, 2)), direction=2)
    with pytest.raises(ValueError, match="samples"):
        swap_times(np.arange(3), np.zeros((5, 2)), np.ones((5, 2)))
