"""Dynamic zero-abduction surface: analytic Jacobian, asymmetric fit, plot."""

import numpy as np
import pytest

from handflow.plugins.mapping.zero_abduction import (
    DEFAULT_SHAPE,
    fit_zero_abduction,
    plot_zero_abduction,
    zero_level,
    zero_level_jacobian,
)

TRUE_H, TRUE_LAM = 215.0, (1.1, 0.2, 15.0, 1.8, 0.3, 20.0)


def _data(n=400, noise=3.0, seed=0):
    rng = np.random.default_rng(seed)
    a, b = rng.uniform(40, 200, n), rng.uniform(40, 200, n)
    return a, b, zero_level(a, b, TRUE_H, TRUE_LAM) - np.abs(rng.normal(0, noise, n))


def test_default_shape_is_symmetric_parabola_in_flex_difference():
    a, b = np.array([50.0, 120, 80]), np.array([50.0, 80, 120])
    s = zero_level(a, b, 200.0, DEFAULT_SHAPE)
    assert s[0] == 200.0 and s[1] == s[2] < 200.0


def test_jacobian_matches_finite_differences():
    a, b, _ = _data(50)
    p = np.r_[TRUE_H, TRUE_LAM]
    jac = zero_level_jacobian(a, b, p[0], p[1:])
    eps = 1e-6
    for i in range(7):
        dp = np.eye(7)[i] * eps
        num = (zero_level(a, b, (p + dp)[0], (p + dp)[1:]) - zero_level(a, b, (p - dp)[0], (p - dp)[1:])) / (2 * eps)
        np.testing.assert_allclose(jac[:, i], num, rtol=1e-5, atol=1e-6)


def test_fit_stays_above_the_data_and_recovers_the_surface():
    a, b, s = _data()
    fit = fit_zero_abduction(a, b, s)
    assert np.all(zero_level(a, b, fit.h, fit.lam) >= s - 1e-9)
    assert fit.n_above == 0
    grid_a, grid_b = np.meshgrid(np.linspace(50, 190, 15), np.linspace(50, 190, 15))
    err = zero_level(grid_a, grid_b, fit.h, fit.lam) - zero_level(grid_a, grid_b, TRUE_H, TRUE_LAM)
    assert np.abs(err).max() < 6.0


def test_asymmetric_loss_prefers_over_estimation():
    a, b, _ = _data(noise=0.0)
    rng = np.random.default_rng(5)
    s = zero_level(a, b, TRUE_H, TRUE_LAM) + rng.normal(0, 4, a.size)  # symmetric noise
    sym = fit_zero_abduction(a, b, s, under_weight=1.0, cover=0.5)
    asym = fit_zero_abduction(a, b, s, under_weight=30.0, cover=0.5)
    r_sym = s - zero_level(a, b, sym.h, sym.lam)
    r_asym = s - zero_level(a, b, asym.h, asym.lam)
    assert (r_asym > 0).mean() < (r_sym > 0).mean()


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="≥ 7 samples"):
        fit_zero_abduction([1, 2], [1, 2], [1, 2])


def test_plot_is_written(tmp_path):
    a, b, s = _data(60)
    plot_zero_abduction(a, b, s, TRUE_H, TRUE_LAM, path=str(tmp_path / "za.png"))
    assert (tmp_path / "za.png").stat().st_size > 1000
