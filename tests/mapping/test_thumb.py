"""Analytic ShadowHand thumb mapping: round trip, rotation-matrix agreement, singularity."""

import numpy as np

from handflow.plugins.hands.joints import HUMAN, SHADOW
from handflow.plugins.mapping.thumb import shadow_to_thumb, thumb_axis_human, thumb_axis_shadow, thumb_to_shadow

A = HUMAN.index("th_abduction")
B = HUMAN.index("th_roll")


def _grid(n=121):
    a = np.linspace(HUMAN.lower[A], HUMAN.upper[A], n)
    b = np.linspace(HUMAN.lower[B], HUMAN.upper[B], n)
    return np.meshgrid(a, b)


def test_round_trip_alpha_beta_over_the_joint_ranges():
    alpha, beta = _grid()
    alpha2, beta2 = shadow_to_thumb(*thumb_to_shadow(alpha, beta))
    mask = alpha > 1e-6  # β is undefined at α = 0 (not inside the range anyway)
    assert np.abs(alpha2 - alpha).max() < 1e-9
    assert np.abs(beta2 - beta)[mask].max() < 1e-9


def test_round_trip_theta_over_the_shadow_ranges():
    t0, t1 = np.meshgrid(
        np.linspace(SHADOW.lower[SHADOW.index("THJ5")], SHADOW.upper[SHADOW.index("THJ5")], 101),
        np.linspace(1e-3, SHADOW.upper[SHADOW.index("THJ4")], 101),
    )
    t0b, t1b = thumb_to_shadow(*shadow_to_thumb(t0, t1))
    assert np.abs(t0b - t0).max() < 1e-9 and np.abs(t1b - t1).max() < 1e-9


def test_agrees_with_rotation_matrix_construction():
    rng = np.random.default_rng(0)
    for t0, t1 in rng.uniform([-1.0, 0.0], [1.0, 1.2], (50, 2)):
        alpha, beta = shadow_to_thumb(t0, t1)
        np.testing.assert_allclose(thumb_axis_shadow(t0, t1), thumb_axis_human(alpha, beta), atol=1e-12)
    for alpha, beta in rng.uniform([0.4, 0.0], [1.7, 1.5], (50, 2)):
        t0, t1 = thumb_to_shadow(alpha, beta)
        np.testing.assert_allclose(thumb_axis_shadow(t0, t1), thumb_axis_human(alpha, beta), atol=1e-12)


def test_singularity():
    # Θ1 = 0: the thumb axis lies on the Θ0 axis, (α, β) = (45°, 0) whatever Θ0 is
    for t0 in np.linspace(-1, 1, 5):
        alpha, beta = shadow_to_thumb(t0, 0.0)
        assert abs(alpha - np.pi / 4) < 1e-12 and abs(beta) < 1e-12
    t0, t1 = thumb_to_shadow(np.pi / 4, 0.0)
    assert abs(t1) < 1e-15 and t0 == 0.0
    assert thumb_to_shadow(np.pi / 4, 0.0, theta0_at_singularity=0.3)[0] == 0.3
    # close to it Θ1 is small, finite, and the round trip stays exact
    alpha, beta = np.pi / 4 + 1e-7, 1e-7
    t0, t1 = thumb_to_shadow(alpha, beta)
    assert 0 < t1 < 1e-6
    a2, b2 = shadow_to_thumb(t0, t1)
    assert abs(a2 - alpha) < 1e-12 and abs(b2 - beta) < 1e-12
