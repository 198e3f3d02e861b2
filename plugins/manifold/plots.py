"""Training plots (PNG, Agg canvas; pyplot's global state is never touched)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def _save(fig, path):
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return path


def latent_grid_curves(model, n_fixed=5, n_points=120):
    """Curves in latent space: each dimension swept over its range, the others held at a few
    quantiles of the training latents (for the manifold plot)."""
    X, periodic = model.latents_, model.periodic_
    lo = np.where(periodic, 0.0, X.min(axis=0))
    hi = np.where(periodic, np.pi, X.max(axis=0))
    curves = []
    for l in range(X.shape[1]):
        sweep = np.linspace(lo[l], hi[l], n_points)
        fixed = np.quantile(X, np.linspace(0.05, 0.95, n_fixed if X.shape[1] > 1 else 1), axis=0)
        for base in fixed:
            C = np.tile(base, (n_points, 1))
            C[:, l] = sweep
            curves.append(C)
    return curves


def plot_training(model, out_dir):
    """Write latents.png, objective.png and manifold.png into ``out_dir``; returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    X, Y = model.latents_, model.Y_
    _, seq = np.unique(model.sequence_ids_, return_inverse=True)
    paths = []

    fig = Figure(figsize=(6, 4.5))
    ax = fig.add_subplot()
    if X.shape[1] == 1:
        pos = np.concatenate([np.arange((seq == s).sum()) for s in range(seq.max() + 1)])
        order = np.argsort(seq, kind="stable")
        ax.scatter(pos, X[order, 0], c=seq[order], cmap="tab20", s=8)
        ax.set(xlabel="index in sequence", ylabel="latent x1")
    else:
        ax.scatter(X[:, 0], X[:, 1], c=seq, cmap="tab20", s=8)
        ax.set(xlabel="latent x1", ylabel="latent x2")
    ax.set_title("latent coordinates (colour = sequence)")
    paths.append(_save(fig, out / "latents.png"))

    fig = Figure(figsize=(6, 4))
    ax = fig.add_subplot()
    ax.plot(model.history_)
    ax.set(xlabel="step", ylabel="objective E(X)", title="training objective")
    if np.all(model.history_ > 0):
        ax.set_yscale("log")
    paths.append(_save(fig, out / "objective.png"))

    dims = min(3, Y.shape[1])
    fig = Figure(figsize=(6, 5))
    ax = fig.add_subplot(projection="3d" if dims == 3 else None)
    ax.scatter(*Y[:, :dims].T, s=4, c="0.6", label="data")
    for n, C in enumerate(latent_grid_curves(model)):
        ax.plot(*model.inverse_transform(C)[:, :dims].T, "r-", lw=1, label="manifold f(x)" if n == 0 else None)
    ax.legend()
    ax.set_title(f"data vs reconstructed manifold (dims 1–{dims})")
    paths.append(_save(fig, out / "manifold.png"))
    return paths
