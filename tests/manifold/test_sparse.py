"""Neighbour-list UKR (sparse.py) against the dense code and finite differences."""

import numpy as np
import pytest

from handflow.plugins.manifold import StructuredUKR
from handflow.plugins.manifold import sparse as sparse_module
from handflow.plugins.manifold.config import ModelConfig, TrainingConfig, build_model
from handflow.plugins.manifold.kernels import Kernel, ProductKernel
from handflow.plugins.manifold.objective import Objective, SequenceLayout
from handflow.plugins.manifold.projection import Manifold
from handflow.plugins.manifold.sparse import SPARSE_MIN_N, SparseManifold, SparseObjective, dense_advice
from handflow.plugins.manifold.validation import InvalidInputError
from tests.manifold.test_gradients import fd_grad

LAYOUTS = {
    "time+quartic": [("periodic_quartic", 4.0), ("quartic", 3.0)],
    "epanechnikov": [("epanechnikov", 6.0)],
    "time": [("periodic_quartic", 5.0)],
}


def problem(layout, N=120, seed=0):
    rng = np.random.default_rng(seed)
    kern = ProductKernel(LAYOUTS[layout])
    X = np.c_[rng.uniform(0, np.pi, N), rng.uniform(0, 1, (N, kern.q - 1))][:, : kern.q]
    if not kern.periodic[0]:
        X[:, 0] /= np.pi
    Y = np.c_[np.cos(2 * X[:, 0]), np.sin(2 * X[:, 0]), X.sum(axis=1)] + rng.normal(0, 0.05, (N, 3))
    return kern, X, Y, SequenceLayout(np.repeat(np.arange(6), N // 6))


def both(layout, loo=True, lam=0.5, **kw):
    kern, X, Y, lay = problem(layout, **kw)
    time = 0 if kern.periodic[0] else None
    lam = lam if time is not None else 0.0
    args = dict(time_dim=time, lambda_cseq=lam, lambda_pvar=lam, loo_cv=loo)
    return Objective(Y, kern, lay, **args), SparseObjective(Y, kern, lay, **args), X


@pytest.mark.parametrize("loo", [True, False])
@pytest.mark.parametrize("layout", LAYOUTS)
def test_sparse_equals_dense(layout, loo):
    dense, sparse, X = both(layout, loo)
    (v1, g1), (v2, g2) = dense(X), sparse(X)
    assert v2 == pytest.approx(v1, rel=1e-12)
    np.testing.assert_allclose(g2, g1, rtol=1e-9, atol=1e-12 * np.abs(g1).max())
    assert 0 < sparse.pairs.mean_neighbours < 0.5 * len(X)  # really sparse


@pytest.mark.parametrize("layout", ["time+quartic", "time"])
def test_sparse_gradient_finite_differences(layout):
    _, sparse, X = both(layout, N=36)
    np.testing.assert_allclose(sparse(X)[1], fd_grad(lambda Z: sparse(Z)[0], X), rtol=1e-5, atol=1e-8)


def test_rebuild_schedule_follows_movement():
    dense, sparse, X = both("time+quartic")
    sparse(X)
    sparse(X + 0.01 / 4)  # well inside the skin: no rebuild
    assert sparse.pairs.n_builds == 1
    moved = np.c_[np.mod(X[:, 0] + np.linspace(0, 0.3, len(X)), np.pi), X[:, 1] * 1.5]
    v, g = sparse(moved)
    assert sparse.pairs.n_builds == 2
    assert v == pytest.approx(dense(moved)[0], rel=1e-12)
    np.testing.assert_allclose(g, dense(moved)[1], rtol=1e-9, atol=1e-12)


def test_float32_is_close():
    dense, _, X = both("time+quartic")
    single = SparseObjective(dense.Y, dense.kernel, dense.layout, time_dim=0, dtype=np.float32)
    (v1, g1), (v2, g2) = dense.reconstruction(X), single.reconstruction(X)
    assert v2 == pytest.approx(v1, rel=1e-5)
    assert np.abs(g2 - g1).max() <= 1e-4 * np.abs(g1).max()


def test_sparse_manifold_matches_dense():
    kern, X, Y, _ = problem("time+quartic", N=200)
    dense, sparse = Manifold(kern, X, Y), SparseManifold(kern, X, Y)
    Xq = np.c_[np.linspace(0, np.pi, 30, endpoint=False), np.linspace(0.1, 0.9, 30)]
    (F1, J1), (F2, J2) = dense.f_and_jacobian(Xq), sparse.f_and_jacobian(Xq)
    np.testing.assert_allclose(F2, F1, atol=1e-12)
    np.testing.assert_allclose(J2, J1, atol=1e-10)
    Yq = Y[::7] + 0.01
    np.testing.assert_allclose(sparse.project(Yq), dense.project(Yq), atol=1e-9)


def test_periodic_quartic_support():
    k = Kernel("periodic_quartic", 4.0)
    assert k.compact and k.support == pytest.approx(np.arcsin(0.25))
    inside = np.array([k.support * 0.99, np.pi - k.support * 0.99])
    assert np.all(k(inside) > 0) and np.all(k(inside + np.array([0.02, -0.02])) == 0)
    assert not Kernel("periodic_quartic", 1.0).compact and not Kernel("gaussian", 2.0).compact


def _rings(n_seq=4, n=30, seed=0):
    rng = np.random.default_rng(seed)
    t = np.pi * np.arange(n) / n
    return [np.c_[np.cos(2 * t), np.sin(2 * t), 0.2 * s + 0 * t] + rng.normal(0, 0.02, (n, 3)) for s in range(n_seq)]


COMPACT = [{"kernel": "periodic_quartic", "beta": 4.0, "time": True}, {"kernel": "quartic", "beta": 2.0}]


def test_estimator_sparse_fit_matches_dense_and_projects():
    seqs = _rings()
    args = dict(latent=COMPACT, n_steps=15, init="equidistant", random_state=0)
    dense = StructuredUKR(sparse=False, **args).fit(seqs)
    sparse = StructuredUKR(sparse=True, **args).fit(seqs)
    assert sparse.sparse_ and not dense.sparse_
    np.testing.assert_allclose(sparse.history_, dense.history_, rtol=1e-9)
    np.testing.assert_allclose(sparse.transform(seqs[1]), dense.transform(seqs[1]), atol=1e-8)


def test_auto_threshold_and_clear_errors():
    small = StructuredUKR(latent=COMPACT, n_steps=0, init="equidistant").fit(_rings())
    assert not small.sparse_  # below SPARSE_MIN_N
    with pytest.raises(InvalidInputError, match="periodic_quartic"):
        StructuredUKR(latent=[{"kernel": "periodic", "beta": 4, "time": True}], sparse=True).fit(_rings())
    with pytest.raises(InvalidInputError, match="sparse must be"):
        StructuredUKR(latent=COMPACT, sparse="yes").fit(_rings())
    model = StructuredUKR(latent=[{"kernel": "gaussian", "beta": 2}], lambda_cseq=0, lambda_pvar=0)
    msg = dense_advice(model, SPARSE_MIN_N)
    assert "quartic or epanechnikov" in msg and "GB" in msg
    assert dense_advice(model, SPARSE_MIN_N - 1) is None
    assert dense_advice(StructuredUKR(latent=COMPACT), 10 * SPARSE_MIN_N) is None


def test_config_reaches_sparse_path():
    """Manipulation manifolds and `handflow train` build their estimator from this config."""
    cfg = ModelConfig(latent=COMPACT, sparse="float32")
    model = build_model(cfg, TrainingConfig(n_steps=3, init="equidistant")).fit(_rings())
    assert model.sparse_ and model.sparse == "float32"
    assert np.all(np.isfinite(model.history_))


def test_too_dense_latents_are_refused_not_allocated():
    kern = ProductKernel([("quartic", 0.5)])
    X = np.linspace(0, 1, 600)[:, None]
    obj = SparseObjective(np.c_[X, X**2], kern, SequenceLayout(np.zeros(600)), loo_cv=True)
    assert obj.reconstruction(X, gradient=False)[0] == np.inf
    with pytest.raises(InvalidInputError, match="raise beta"):
        obj(X)


def test_segmenter_class_models_train_on_every_point_sparse(monkeypatch):
    from handflow.plugins.segmenter.models import fit_class_models

    monkeypatch.setattr(sparse_module, "SPARSE_MIN_N", 500)  # keep the test small
    rng = np.random.default_rng(1)
    t = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    segs = [
        np.c_[np.cos(t * (1 + 0.01 * i)), np.sin(t), 0.1 * i + 0 * t] + rng.normal(0, 0.01, (100, 3)) for i in range(8)
    ]
    models = fit_class_models({"a": segs}, n_steps=2, kernel="periodic_quartic", max_points=300)
    assert models["a"].sparse_ and len(models["a"].Y_) == 800  # max_points ignored: every point
    with pytest.raises(ValueError, match="kernel must be one of"):
        fit_class_models({"a": segs}, kernel="gaussian")


def _long_npz(tmp_path, n_seq=6, n=100):
    rng = np.random.default_rng(0)
    t = np.pi * np.arange(n) / n
    arrays = {
        f"s{i}": np.c_[np.cos(2 * t), np.sin(2 * t), 0.1 * i + 0 * t] + rng.normal(0, 0.01, (n, 3))
        for i in range(n_seq)
    }
    np.savez(tmp_path / "long.npz", **arrays)
    return "long.npz"


@pytest.mark.parametrize("compact", [True, False])
def test_train_command_picks_sparse_or_names_compact_kernels(tmp_path, capsys, monkeypatch, compact):
    from tests.manifold.test_train_command import run, write_config

    monkeypatch.setattr(sparse_module, "SPARSE_MIN_N", 500)  # keep the test small
    time = {"kernel": "periodic_quartic" if compact else "periodic", "beta": 20.0, "time": True}
    cfg = write_config(tmp_path, {"npz": _long_npz(tmp_path)}, latent=[time], init="equidistant")
    out = tmp_path / "m.npz"
    assert run(cfg, "--out", out, "--steps", "2") == 0
    err = capsys.readouterr().err
    assert StructuredUKR.load(out).sparse_ is compact
    assert ("latent[0]: periodic (beta 20) -> periodic_quartic" in err) is not compact
