"""Optimisers for the UKR objective (docs/training.md): iRprop± and L-BFGS.

Both keep the *best* latents seen (RPROP is not monotone), report progress through
``callback(step, value)`` and stop cleanly on ``KeyboardInterrupt`` (``interrupted=True``),
returning the best latents so far.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize
from threadpoolctl import ThreadpoolController


@dataclass
class OptimResult:
    X: np.ndarray
    value: float
    history: list = field(default_factory=list)  # objective per step (index 0 = initial)
    n_evaluations: int = 0
    interrupted: bool = False


class _Best:
    def __init__(self):
        self.value, self.X, self.n = np.inf, None, 0

    def update(self, value, X):
        self.n += 1
        if value < self.value:  # NaN never becomes the best
            self.value, self.X = value, X.copy()


def rprop(
    fun,
    X0,
    n_steps,
    *,
    wrap=None,
    callback=None,
    variant="minus",
    delta0=0.01,
    delta_min=1e-6,
    delta_max=0.2,
    eta_plus=1.2,
    eta_minus=0.5,
):
    """iRprop− (``variant="minus"``) or iRprop+ (Igel & Hüsken 2000) for ``n_steps`` steps.

    ``fun(X) -> (value, grad)``; ``wrap(X)`` maps periodic coordinates back after each step.
    Documented choices: initial step 0.01, bounds [1e-6, 0.2] (latent units; the periodic
    dimension spans π), η+ = 1.2, η− = 0.5.
    """
    if variant not in ("minus", "plus"):
        raise ValueError(f"unknown RPROP variant {variant!r}; use 'minus' or 'plus'")
    X = np.array(X0, dtype=float, copy=True)
    best, history = _Best(), []
    delta = np.full_like(X, delta0)
    g_prev, step_prev, v_prev = np.zeros_like(X), np.zeros_like(X), np.inf
    interrupted = False
    try:
        for step in range(n_steps + 1):
            value, g = fun(X)
            best.update(value, X)
            history.append(value)
            if callback is not None:
                callback(step, value)
            if step == n_steps:
                break
            prod = g * g_prev
            delta = np.where(
                prod > 0,
                np.minimum(delta * eta_plus, delta_max),
                np.where(prod < 0, np.maximum(delta * eta_minus, delta_min), delta),
            )
            flip = prod < 0
            move = -np.sign(g) * delta
            if variant == "plus":
                move = np.where(flip, -step_prev if value > v_prev else 0.0, move)
            else:
                move[flip] = 0.0
            g = np.where(flip, 0.0, g)
            X = X + move
            if wrap is not None:
                X = wrap(X)
            g_prev, step_prev, v_prev = g, move, value
    except KeyboardInterrupt:
        interrupted = True
    if best.X is None:
        raise FloatingPointError("the objective was never finite; check the data scaling and beta")
    return OptimResult(best.X, float(best.value), history, best.n, interrupted)


def _scipy_blas_single_thread():
    """scipy ships its own OpenBLAS; its idle threads spinning next to numpy's pool on a
    2-core machine slowed L-BFGS-B >10x (measured).  Limit scipy's pool to 1 thread."""
    ctl = ThreadpoolController()
    libs = [c.filepath for c in ctl.lib_controllers if "scipy" in c.filepath and "numpy" not in c.filepath]
    return ctl.select(filepath=libs).limit(limits=1) if libs else contextlib.nullcontext()


def lbfgs(fun, X0, n_steps, *, wrap=None, callback=None):
    """scipy L-BFGS-B with at most ``n_steps`` iterations; history = objective per iteration."""
    X0 = np.asarray(X0, dtype=float)
    shape, best, history = X0.shape, _Best(), []

    def f(x):
        X = x.reshape(shape)
        value, g = fun(X)
        best.update(value, X)
        return value, g.ravel()

    def record(value):
        history.append(float(value))
        if callback is not None:
            callback(len(history) - 1, history[-1])

    interrupted = False
    try:
        record(f(X0.ravel())[0])
        if n_steps > 0:
            with _scipy_blas_single_thread():
                minimize(
                    f,
                    X0.ravel(),
                    jac=True,
                    method="L-BFGS-B",
                    callback=lambda intermediate_result: record(intermediate_result.fun),
                    options={"maxiter": n_steps, "maxfun": 4 * n_steps, "ftol": 0.0, "gtol": 0.0},
                )
    except KeyboardInterrupt:
        interrupted = True
    if best.X is None:
        raise FloatingPointError("the objective was never finite; check the data scaling and beta")
    X = best.X if wrap is None else wrap(best.X)
    return OptimResult(X, float(best.value), history, best.n, interrupted)


OPTIMIZERS = {"rprop": rprop, "lbfgs": lbfgs}
