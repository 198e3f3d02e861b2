"""Analytic gradients vs central finite differences (every kernel and penalty,
periodic and not, LOO on and off)."""

import numpy as np
import pytest

from handflow.plugins.manifold.kernels import KERNEL_NAMES, Kernel, ProductKernel
from handflow.plugins.manifold.objective import Objective, SequenceLayout


def fd_grad(fun, X, h=1e-6):
    g = np.zeros_like(X)
    for idx in np.ndindex(X.shape):
        Xp, Xm = X.copy(), X.copy()
        Xp[idx] += h
        Xm[idx] -= h
        g[idx] = (fun(Xp) - fun(Xm)) / (2 * h)
    return g


def make(names, loo, time_dim=0, lc=0.0, lp=0.0, seed=0):
    rng = np.random.default_rng(seed)
    N = 24
    Y = rng.standard_normal((N, 3))
    kern = ProductKernel([(n, 2.0 if n == "periodic" else 1.0) for n in names])
    X = rng.uniform(0, 1.5, (N, len(names)))
    ids = np.repeat(np.arange(4), N // 4)
    return Objective(Y, kern, SequenceLayout(ids), time_dim=time_dim, lambda_cseq=lc, lambda_pvar=lp, loo_cv=loo), X


LAYOUTS = [(n,) for n in KERNEL_NAMES] + [
    ("periodic", "gaussian"),
    ("gaussian", "quartic"),
    ("periodic", "epanechnikov", "gaussian"),
]


@pytest.mark.parametrize("loo", [True, False])
@pytest.mark.parametrize("names", LAYOUTS, ids="-".join)
def test_reconstruction_gradient(names, loo):
    obj, X = make(names, loo)
    value, grad = obj.reconstruction(X)
    fd = fd_grad(lambda Z: obj.reconstruction(Z, gradient=False)[0], X)
    assert value > 0
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-7 * np.abs(fd).max())


@pytest.mark.parametrize("time_kernel", ["periodic", "gaussian"])
@pytest.mark.parametrize("term", ["cseq", "pvar"])
def test_penalty_gradient(term, time_kernel):
    obj, X = make((time_kernel, "gaussian"), True, lc=1.0, lp=1.0)
    value, grad = getattr(obj, term)(X)
    fd = fd_grad(lambda Z: getattr(obj, term)(Z)[0], X)
    assert value > 0
    np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize("loo", [True, False])
def test_total_gradient(loo):
    obj, X = make(("periodic", "quartic"), loo, lc=0.7, lp=1.3)
    fd = fd_grad(lambda Z: obj(Z, gradient=False)[0], X)
    np.testing.assert_allclose(obj(X)[1], fd, rtol=1e-5, atol=1e-8)


@pytest.mark.parametrize("name", KERNEL_NAMES)
def test_kernel_derivative_and_low_rank_matrix(name):
    k = Kernel(name, 1.7)
    d = np.linspace(-1.2, 1.2, 41) + 0.013  # avoid the Epanechnikov kink exactly at 1
    np.testing.assert_allclose(k.derivative(d), (k(d + 1e-6) - k(d - 1e-6)) / 2e-6, atol=1e-6)
    rng = np.random.default_rng(1)
    A, B = rng.uniform(-1, 1, (7, 1)), rng.uniform(-1, 1, (5, 1))
    pk = ProductKernel([k])
    np.testing.assert_allclose(pk.matrix(A, B), k(A - B.T), atol=1e-12)
    K, C = pk.matrix(A, B, with_du=True)
    np.testing.assert_allclose(pk.derivatives(K, C, A, B)[0], k.derivative(A - B.T), atol=1e-10)


def test_product_kernel_is_product():
    rng = np.random.default_rng(2)
    A, B = rng.uniform(0, 2, (6, 2)), rng.uniform(0, 2, (4, 2))
    ks = [Kernel("periodic", 3.0), Kernel("quartic", 0.8)]
    ref = ks[0](A[:, :1] - B[:, 0]) * ks[1](A[:, 1:] - B[:, 1])
    np.testing.assert_allclose(ProductKernel(ks).matrix(A, B), ref, atol=1e-12)
