import numpy as np
import pytest

from handflow.plugins.segmenter.clm import CompetitiveLayerModel, clm_energy, largest_eigenvalue
from handflow.plugins.segmenter.clm import _solver as clm_solver
from handflow.plugins.segmenter.compatibility import background_band


def random_layers(n=40, width=5, layers=3, seed=0):
    rng = np.random.default_rng(seed)
    band = rng.uniform(-1, 1, size=(layers, n, width))
    for k in range(1, width + 1):
        band[:, n - k :, k - 1] = 0.0
    bg, d = background_band(n, width, 0.5, width)
    return np.concatenate([band, bg[None]]), np.r_[np.zeros(layers), d]


def dense(band_row, diag):
    n, width = band_row.shape
    A = np.eye(n) * diag
    for k in range(1, width + 1):
        idx = np.arange(n - k)
        A[idx, idx + k] = A[idx + k, idx] = band_row[: n - k, k - 1]
    return A


def test_largest_eigenvalue_matches_dense():
    band, diag = random_layers()
    for a in range(band.shape[0]):
        assert largest_eigenvalue(band[a], diag[a]) == pytest.approx(np.linalg.eigvalsh(dense(band[a], diag[a]))[-1])


def test_largest_eigenvalue_of_long_sequences_matches_dense():  # the Lanczos path (N >= 200)
    band, diag = random_layers(n=300, width=6)
    band[1] = 0.0  # an all-zero layer: its eigenvalue is the diagonal
    for a in range(band.shape[0]):
        assert largest_eigenvalue(band[a], diag[a]) == pytest.approx(np.linalg.eigvalsh(dense(band[a], diag[a]))[-1])


def test_largest_eigenvalue_by_bisection_matches_dense(monkeypatch):  # the path from BISECTION_MIN_N on
    monkeypatch.setattr(clm_solver, "BISECTION_MIN_N", 250)
    band, diag = random_layers(n=300, width=6)
    band[1] = -0.4  # near-constant compatibilities: crowded top eigenvalues, Lanczos's slow case
    for a in range(band.shape[0]):
        exact = np.linalg.eigvalsh(dense(band[a], diag[a]))[-1]
        assert largest_eigenvalue(band[a], diag[a]) == pytest.approx(exact, rel=1e-12, abs=1e-12)


def test_energy_matches_dense_formula():
    band, diag = random_layers(n=12, width=3)
    x = np.random.default_rng(1).uniform(0, 1, size=(band.shape[0], 12))
    J, I, T = 2.0, 7.0, 0.3
    lateral = sum(x[a] @ dense(band[a], diag[a]) @ x[a] for a in range(band.shape[0]))
    expected = -J * x.sum() + 0.5 * I * np.sum(x.sum(axis=0) ** 2) - 0.5 * lateral + 0.5 * T * np.sum(x * x)
    assert clm_energy(x, band, diag, J, I, T) == pytest.approx(expected)


def test_energy_never_increases_over_sweeps_at_fixed_temperature():
    band, diag = random_layers()
    I, T = 12.0, 1.5
    clm = CompetitiveLayerModel(inhibition=I, eta=1.0, max_sweeps=1, random_state=3)
    x = clm.initial_activities((band.shape[0], band.shape[1]))
    energies = [clm_energy(x, band, diag, 2.0, I, T)]
    for _ in range(30):
        x = clm.solve(band, diag, x0=x, temperature=T).activities
        energies.append(clm_energy(x, band, diag, 2.0, I, T))
    assert np.all(np.diff(energies) <= 1e-9 * np.abs(energies[:-1]).max())
    assert energies[-1] < energies[0]


def test_solver_converges_to_one_active_layer_per_observation():
    band, diag = random_layers(n=60)
    res = CompetitiveLayerModel(random_state=0).solve(band, diag)
    assert res.converged
    assert np.all((res.activities > 0).sum(axis=0) == 1)
    assert np.all(res.winners >= 0)


def test_solver_is_deterministic_given_a_seed():
    band, diag = random_layers()
    a = CompetitiveLayerModel(random_state=7).solve(band, diag)
    b = CompetitiveLayerModel(random_state=7).solve(band, diag)
    np.testing.assert_array_equal(a.activities, b.activities)
    assert a.sweeps == b.sweeps


def test_solver_rejects_bad_compatibilities():
    band, diag = random_layers()
    band[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        CompetitiveLayerModel().solve(band, diag)
    with pytest.raises(ValueError, match="one diagonal value per layer"):
        CompetitiveLayerModel().solve(band[:, :, :], diag[:2])


def test_gershgorin_bound_is_above_the_largest_eigenvalue():
    from handflow.plugins.segmenter.clm import gershgorin_bound

    band, diag = random_layers()
    exact = max(largest_eigenvalue(band[a], diag[a]) for a in range(band.shape[0]))
    bound = gershgorin_bound(band, diag)
    dense_rows = max(np.abs(dense(band[a], diag[a])).sum(axis=1).max() for a in range(band.shape[0]))
    assert exact <= bound == pytest.approx(dense_rows)


def test_error_scale_weakens_the_reconstruction_penalty(candidates, two_letters):
    from handflow.plugins.segmenter import CLMSegmenter

    Y, _ = two_letters
    proj = candidates.project(Y)
    base, _ = CLMSegmenter(candidates, history=5).layer_compatibilities(proj)
    scaled, _ = CLMSegmenter(candidates, history=5, error_scale=0.1).layer_compatibilities(proj)
    live = base[:-1] != 0
    assert np.all(scaled[:-1][live] >= base[:-1][live] - 1e-12)  # c_sre grows as e shrinks
    assert np.any(scaled[:-1][live] > base[:-1][live] + 1e-3)
    with pytest.raises(ValueError, match="error_scale"):
        CLMSegmenter(candidates, error_scale=0.0).layer_compatibilities(proj)


def test_clm_estimators_store_only_and_clone():
    from sklearn.base import clone
    from sklearn.exceptions import NotFittedError

    from handflow.plugins.segmenter import CLMSegmenter

    clm = CompetitiveLayerModel(eta=0.8, random_state=3)
    assert "rng_" not in vars(clm) and clm.get_params()["eta"] == 0.8
    with pytest.raises(TypeError):
        CompetitiveLayerModel(2.0)  # hyper-parameters are keyword-only
    band, diag = np.zeros((2, 6, 3)), np.zeros(2)
    band[0, :3, 0] = band[1, 3:, 0] = 1.0
    first = clm.solve(band, diag).winners
    assert np.array_equal(clone(clm).solve(band, diag).winners, first)  # same seed, same run
    seg = CLMSegmenter(history=3, restarts=0, random_state=1)
    assert "solver_" not in vars(seg)  # no solver, no generator in the constructor
    with pytest.raises(NotFittedError, match="fit_predict"):
        _ = seg.labels_
    with pytest.raises(ValueError, match="restarts"):
        seg.fit_predict_bands(*seg.with_background(band))
    seg.set_params(restarts=2)
    assert seg.get_params()["restarts"] == 2 and clone(seg).get_params() == seg.get_params()
    labels = seg.fit_predict_bands(*seg.with_background(band))
    assert labels.shape == (6,) and hasattr(seg, "labels_")
    assert np.array_equal(clone(seg).fit_predict_bands(*seg.with_background(band)), labels)


def test_run_advanced_in_pieces_ends_at_a_fixed_point_like_one_solve():
    band, diag = random_layers(n=60)
    clm = CompetitiveLayerModel(random_state=0)
    x0 = clm.initial_activities((band.shape[0], band.shape[1]))
    run = clm.start(band, diag, x0=x0)
    pieces = 0
    while not run.advance(7):
        pieces += 1
    assert run.converged and pieces > 1 and run.sweeps <= clm.max_sweeps
    res = run.result()
    one = CompetitiveLayerModel(random_state=0).solve(band, diag, x0=x0)
    np.testing.assert_array_equal(res.winners, one.winners)
    # fixed point of the un-annealed dynamics: every neuron is its own coordinate-wise minimiser
    x, inhib = res.activities, res.inhibition
    L, N, B = band.shape
    for a in range(L):
        for r in range(N):
            lat = sum(band[a, r, k - 1] * x[a, r + k] for k in range(1, B + 1) if r + k < N)
            lat += sum(band[a, r - k, k - 1] * x[a, r - k] for k in range(1, B + 1) if r - k >= 0)
            best = max(0.0, (2.0 - inhib * (x[:, r].sum() - x[a, r]) + lat) / (inhib - diag[a]))
            assert abs(best - x[a, r]) <= 1e-2 * x.max()


def test_per_column_temperature_freezes_cold_columns():
    band, diag = random_layers(n=40)
    clm = CompetitiveLayerModel(random_state=1, max_sweeps=5)
    settled = CompetitiveLayerModel(random_state=1).solve(band, diag)
    T = np.zeros(40)
    T[-5:] = 50.0  # only the last columns are hot
    x0 = settled.activities.copy()
    x0[:, -5:] = 0.01
    res = clm.solve(band, diag, x0=x0, temperature=T)
    np.testing.assert_allclose(res.temperature[-5:], 50.0 * clm.eta**res.sweeps)
    assert np.all(res.temperature[:-5] == 0.0)
    np.testing.assert_array_equal(res.winners[:30], settled.winners[:30])


def test_columns_before_first_are_a_fixed_context():
    band, diag = random_layers(n=50)
    clm = CompetitiveLayerModel(random_state=2)
    x0 = clm.solve(band, diag).activities
    x0[:, 30:] = 0.01
    run = clm.start(band, diag, x0=x0.copy(), first=30)
    run.advance(clm.max_sweeps)
    np.testing.assert_array_equal(run.x[:, :30], x0[:, :30])
    assert run.converged and np.all((run.x[:, 30:] > 0).sum(axis=0) == 1)
    with pytest.raises(ValueError, match="first"):
        clm.start(band, diag, first=50)
