"""Behaviour of the StructuredUKR estimator."""

import numpy as np
import pytest
from sklearn.exceptions import NotFittedError

from handflow.plugins.manifold import InvalidInputError, LatentDim, StructuredUKR, toy
from handflow.plugins.manifold.kernels import Kernel, ProductKernel
from handflow.plugins.manifold.objective import Objective, SequenceLayout
from tests.manifold.ukr_helpers import CYL_LATENT, RING_LATENT, closed_curves


def circdist(a, b):
    """Distance on the periodic latent axis [0, π)."""
    d = np.mod(np.abs(a - b), np.pi)
    return np.minimum(d, np.pi - d)


def test_periodic_wrap():
    k = Kernel("periodic", 5.0)
    d = np.linspace(-3, 3, 13)
    np.testing.assert_allclose(k(d + np.pi), k(d), atol=1e-12)
    rng = np.random.default_rng(0)
    Y = rng.standard_normal((20, 2))
    obj = Objective(Y, ProductKernel([k]), SequenceLayout(np.repeat([0, 1], 10)), time_dim=0, lambda_cseq=1.0)
    X = rng.uniform(0, np.pi, (20, 1))
    shifted = X + np.pi * rng.integers(-2, 3, X.shape)
    assert obj(shifted)[0] == pytest.approx(obj(X)[0])
    wrapped = ProductKernel([k]).wrap(shifted)
    assert np.all((wrapped >= 0) & (wrapped < np.pi))
    np.testing.assert_allclose(circdist(wrapped, X), 0, atol=1e-12)


def test_fit_latents_stay_in_period(ring_model):
    model, _ = ring_model
    assert np.all((model.latents_ >= 0) & (model.latents_ < np.pi))


def test_loo_cv_prevents_trivial_solution():
    """Without LOO, R → 0 as the latents separate (and optimisation drives them apart);
    with LOO, separating the points makes R worse and training keeps R_cv away from 0."""
    from handflow.plugins.manifold.optimize import rprop

    rng = np.random.default_rng(0)
    Y = rng.standard_normal((30, 3))
    X = rng.permutation(np.linspace(-1, 1, 30))[:, None]
    kern = ProductKernel([("gaussian", 1.0)])
    lay = SequenceLayout(np.zeros(30, int))
    plain = Objective(Y, kern, lay, loo_cv=False)
    loo = Objective(Y, kern, lay, loo_cv=True)
    r_plain = [plain(s * X, False)[0] for s in (1, 30, 300)]
    r_loo = [loo(s * X, False)[0] for s in (1, 30, 300)]
    assert r_plain[-1] < 1e-6 < r_plain[0]
    assert r_loo[-1] > r_loo[0] > 0.5
    trained_plain = rprop(plain, X, 300, delta_max=1.0).X
    trained_loo = rprop(loo, X, 300, delta_max=1.0).X
    assert plain(trained_plain, False)[0] < 1e-3
    assert np.ptp(trained_plain) > 5 * np.ptp(X)
    assert loo(trained_loo, False)[0] > 0.3


def test_training_decreases_objective(ring_model):
    model, _ = ring_model
    assert model.objective_ < model.history_[0]
    assert model.objective_ == pytest.approx(model.history_.min())
    assert len(model.history_) == 151


def test_noise_free_training_sequence_projects_back_near_its_latents():
    seqs = closed_curves(noise=0.0)
    model = StructuredUKR(latent=RING_LATENT, n_steps=100, isomap_neighbors=(10,)).fit(seqs)
    Y = np.vstack(seqs)
    err = circdist(model.transform(Y)[:, 0], model.latents_[:, 0])
    spacing = np.pi / 50
    assert np.median(err) < 0.1 * spacing and err.max() < spacing
    assert model.reconstruction_error(Y).mean() < 1e-2


def test_projection_is_orthogonal_minimum(ring_model):
    model, seqs = ring_model
    y = seqs[1][7] + 0.05
    x = model.transform(y)
    dense = np.linspace(0, np.pi, 4000, endpoint=False)[:, None]
    d_dense = np.sum((model.inverse_transform(dense) - y) ** 2, 1)
    d_x = np.sum((model.inverse_transform(x) - y) ** 2)
    assert d_x <= d_dense.min() + 1e-9


def test_transform_with_mask_ignores_masked_dimensions(ring_model):
    model, seqs = ring_model
    Y = np.vstack(seqs)[::5]
    mask = np.array([1.0, 1.0, 0.0])
    corrupted = Y.copy()
    corrupted[:, 2] = np.random.default_rng(0).normal(0, 50, len(Y))
    np.testing.assert_array_equal(model.transform(corrupted, mask), model.transform(Y, mask))
    # the unmasked projection is affected by the corruption
    assert np.max(circdist(model.transform(corrupted), model.transform(Y))) > 0.1
    # masked reconstruction error ignores dimension 3 as well
    np.testing.assert_allclose(model.reconstruction_error(corrupted, mask), model.reconstruction_error(Y, mask))


def test_reconstruction_error_and_score(ring_model):
    model, seqs = ring_model
    Y = np.vstack(seqs)
    e = model.reconstruction_error(Y)
    r = Y - model.inverse_transform(model.transform(Y))
    np.testing.assert_allclose(e, np.sum(r**2 / Y.var(0), 1))
    assert model.score(Y) == pytest.approx(-e.mean())
    assert model.score(Y + 1.0) < model.score(Y)
    assert np.isscalar(model.reconstruction_error(Y[0]))


def test_shapes_single_and_batch(cylinder_model):
    model, train = cylinder_model
    Y = np.vstack(train)
    assert model.transform(Y).shape == (len(Y), 2)
    assert model.transform(Y[0]).shape == (2,)
    assert model.inverse_transform(model.latents_[:4]).shape == (4, 3)
    assert model.inverse_transform(model.latents_[0]).shape == (3,)


def test_cylinder_height_is_monotonic_in_latent(cylinder_model):
    model, train = cylinder_model
    _, seq = np.unique(model.sequence_ids_, return_inverse=True)
    means = [model.latents_[seq == s, 1].mean() for s in range(len(train))]
    assert np.all(np.diff(means) > 0) or np.all(np.diff(means) < 0)


def test_save_load_identical_predictions(cylinder_model, tmp_path):
    model, train = cylinder_model
    path = tmp_path / "m.npz"
    model.save(path, provenance={"source": "toy"})
    loaded = StructuredUKR.load(path)
    Y = np.vstack(train)
    np.testing.assert_array_equal(loaded.transform(Y), model.transform(Y))
    np.testing.assert_array_equal(loaded.inverse_transform(model.latents_), model.inverse_transform(model.latents_))
    np.testing.assert_array_equal(loaded.reconstruction_error(Y), model.reconstruction_error(Y))
    assert loaded.get_params()["latent"] == CYL_LATENT
    assert loaded.provenance_["source"] == "toy"
    assert loaded.time_dim_ == 0


def test_unknown_format_version_refused(cylinder_model, tmp_path):
    import json

    model, _ = cylinder_model
    path = tmp_path / "m.npz"
    model.save(path)
    with np.load(path) as f:
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays["metadata"][()]))
    meta["format_version"] = 99
    arrays["metadata"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "future.npz", **arrays)
    with pytest.raises(ValueError, match="format version 99, this handflow reads version 1; train it again"):
        StructuredUKR.load(tmp_path / "future.npz")


def test_load_refuses_pickled_content(tmp_path):
    np.savez(tmp_path / "evil.npz", metadata=np.array([{"a": 1}], dtype=object))
    with pytest.raises(ValueError):
        StructuredUKR.load(tmp_path / "evil.npz")


def test_from_latents_without_training():
    seqs = closed_curves()
    X = np.concatenate([np.pi * np.arange(len(s)) / len(s) for s in seqs])[:, None]
    model = StructuredUKR.from_latents(seqs, X, latent=RING_LATENT)
    np.testing.assert_allclose(model.latents_, X)
    assert len(model.history_) == 1
    f0 = model.inverse_transform(X[:3])
    assert f0.shape == (3, 3) and np.all(np.isfinite(f0))


def test_equidistant_init_and_extend():
    seqs = closed_curves(noise=0.01)
    model = StructuredUKR(
        latent=[LatentDim("periodic", 12.0, True)], init="equidistant", n_steps=60, random_state=0
    ).fit(seqs[:1])
    assert model.n_steps == 60
    x_new = model.transform(seqs[1])
    model.extend(seqs[1:2], n_steps=20)
    assert model.n_steps == 60
    assert model.latents_.shape == (len(seqs[0]) + len(seqs[1]), 1)
    assert list(np.unique(model.sequence_ids_)) == [0, 1]
    # the new sequence started from its projection and the retraining kept it close
    assert np.median(circdist(model.latents_[len(seqs[0]) :, 0], x_new[:, 0])) < 0.2


def test_lbfgs_optimizer_and_sequence_ids_input():
    seqs = closed_curves(noise=0.02)
    Y = np.vstack(seqs)
    ids = np.repeat(np.arange(len(seqs)), [len(s) for s in seqs])
    model = StructuredUKR(latent=RING_LATENT, optimizer="lbfgs", n_steps=40, isomap_neighbors=(10,)).fit(Y, ids)
    assert model.objective_ < model.history_[0]
    assert np.all((model.latents_ >= 0) & (model.latents_ < np.pi))


def test_keyboard_interrupt_keeps_best_so_far():
    seqs = closed_curves(noise=0.02)

    def stop(step, value):
        if step == 5:
            raise KeyboardInterrupt

    model = StructuredUKR(latent=RING_LATENT, n_steps=100, isomap_neighbors=(10,))
    model.fit(seqs, callback=stop)
    assert model.interrupted_ and len(model.history_) == 6
    assert model.objective_ == pytest.approx(min(model.history_))


def test_deterministic_given_random_state():
    seqs = closed_curves(noise=0.02)
    a = StructuredUKR(latent=RING_LATENT, n_steps=30, init="equidistant", random_state=4).fit(seqs)
    b = StructuredUKR(latent=RING_LATENT, n_steps=30, init="equidistant", random_state=4).fit(seqs)
    np.testing.assert_array_equal(a.latents_, b.latents_)


# -- bad inputs ---------------------------------------------------------------------------------
GOOD = closed_curves()


@pytest.mark.parametrize(
    "kwargs, data, match",
    [
        ({}, [np.r_[GOOD[0][:-1], [[np.nan, 0, 0]]]], "NaN or inf"),
        ({}, [np.r_[GOOD[0][:-1], [[np.inf, 0, 0]]]], "NaN or inf"),
        ({"init": "equidistant"}, [GOOD[0][:2]], "fewer points than needed"),
        ({}, [GOOD[0], GOOD[1][:, :2]], "inconsistent dimensions"),
        ({"latent": [{"kernel": "cauchy", "beta": 1}]}, GOOD, "unknown kernel 'cauchy'"),
        ({"latent": RING_LATENT, "time_dim": 3}, GOOD, "time dimension index 3 is out of range"),
        ({"latent": [{"kernel": "gaussian", "beta": 1}]}, GOOD, "need a time dimension"),
        ({"latent": [{"kernel": "gaussian", "beta": -1}]}, GOOD, "positive"),
        ({"latent": [{"kernel": "gaussian", "beta": 10**400}]}, GOOD, "latent\\[0\\]"),  # an integer no float holds
        ({}, [np.array([[1, 10**400]])], "must be numeric"),
        ({"latent": CYL_LATENT * 2}, GOOD, "only one latent dimension can be the time"),
        ({"latent": CYL_LATENT + [{"kernel": "gaussian", "beta": 1}]}, GOOD, "fewer dimensions"),
        ({"optimizer": "adam"}, GOOD, "unknown optimizer"),
        ({"latent": CYL_LATENT, "projection_steps": -1}, GOOD, "projection_steps must be >= 0"),
        ({"init": "pca"}, GOOD, "unknown init"),
        ({"init": np.zeros((3, 1))}, GOOD, "init latents must have shape"),
        ({}, [], "no sequences"),
    ],
)
def test_bad_inputs(kwargs, data, match):
    with pytest.raises(InvalidInputError, match=match):
        StructuredUKR(**kwargs).fit(data)


def test_bad_inputs_after_fit(ring_model):
    model, _ = ring_model
    with pytest.raises(InvalidInputError, match="inconsistent dimensions"):
        model.transform(np.zeros((4, 5)))
    with pytest.raises(InvalidInputError, match="NaN"):
        model.transform(np.full((1, 3), np.nan))
    with pytest.raises(InvalidInputError, match="mask"):
        model.transform(np.zeros((2, 3)), mask=[1, 1])
    with pytest.raises(InvalidInputError, match="not all zero"):
        model.transform(np.zeros((2, 3)), mask=[0, 0, 0])
    with pytest.raises(NotFittedError, match="not fitted"):
        StructuredUKR().transform(np.zeros((1, 3)))


def test_toy_measures_sanity(cylinder_model):
    model, train = cylinder_model
    m = toy.evaluate(model, train, random_state=0)
    assert set(m) == {
        "nmse_test",
        "nmse_denoise",
        "bias",
        "param_variance",
        "ring_nvar_map",
        "ring_nvar_project",
        "line_ncmse_map",
        "line_ncmse_project",
    }
    assert 0 < m["nmse_test"] < m["nmse_denoise"] < 0.2
    assert all(0 <= m[k] < 0.2 for k in m if k != "bias")
    assert toy.ncmse([0.1, np.pi - 0.1], np.pi) == pytest.approx(0.01 / (np.pi / 2) ** 2)
    assert toy.nmse(train[0], train[0]) == 0
