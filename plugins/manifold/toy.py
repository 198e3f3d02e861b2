"""Toy cylinder data and the reference error measures (docs/training.md; thesis 5.3.2–5.3.3).

Documented normalisations (the thesis gives none legibly):

* nMSE = mean ‖y − ŷ‖² / mean ‖y − ȳ‖² (total variance of the reference data).
* bias = mean radial shrinkage ``1 − ‖(ŷ_1, ŷ_2)‖`` of f(g(·)) on the noisy training data.
* param_variance = mean over sequences of the within-sequence variance of the non-periodic
  latent coordinate, divided by that coordinate's total variance.
* ring nVAR (map) = per latent ring ``(var r + var z) / (var x + var y + var z)`` of its image
  (variance orthogonal to an axis-centred horizontal ring), averaged over rings.
* ring nVAR (project) = per observed ring the variance of the projected parameter coordinate
  divided by its variance over all projected rings, averaged.
* nCMSE = mean Δ² / (P/2)² with the periodic deviation Δ from the circular mean (period P =
  2π for mapped lines in observation space, π for projected lines), so it lies in [0, 1].
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

TRAIN_HEIGHTS = np.round(np.linspace(0.0, 1.0, 6), 10)
TEST_HEIGHTS = np.round(np.linspace(0.0, 1.0, 11), 10)
POINTS_PER_RING = 45
NOISE = 0.1


def ring(height, n_points=POINTS_PER_RING, phase=0.0):
    """One ordered ring ``(cos φ, sin φ, h)`` of the unit cylinder (one periodic sequence)."""
    phi = phase + 2 * np.pi * np.arange(n_points) / n_points
    return np.column_stack([np.cos(phi), np.sin(phi), np.full(n_points, float(height))])


def cylinder(heights, n_points=POINTS_PER_RING, noise=0.0, random_state=None):
    """List of rings at ``heights``; Gaussian noise σ = ``noise``; a random start phase per
    ring when ``random_state`` is given (noise-free, phase 0 otherwise)."""
    rng = np.random.default_rng(random_state)
    seqs = []
    for h in heights:
        phase = rng.uniform(0, 2 * np.pi) if random_state is not None else 0.0
        r = ring(h, n_points, phase)
        seqs.append(r + rng.normal(0.0, noise, r.shape) if noise else r)
    return seqs


def nmse(Y, Y_hat):
    Y, Y_hat = np.asarray(Y), np.asarray(Y_hat)
    return float(np.mean(np.sum((Y - Y_hat) ** 2, 1)) / np.mean(np.sum((Y - Y.mean(0)) ** 2, 1)))


def ncmse(angles, period):
    """Periodic angular error of ``angles`` around their circular mean, normalised to [0, 1]."""
    a = 2 * np.pi * np.asarray(angles) / period
    mean = np.arctan2(np.sin(a).mean(), np.cos(a).mean()) * period / (2 * np.pi)
    delta = np.mod(np.abs(np.asarray(angles) - mean), period)
    dev = np.where(delta < period / 2, delta, period - delta)
    return float(np.mean(dev**2) / (period / 2) ** 2)


def evaluate(model, train_noisy, random_state=None, n_time=90, n_lines=12):
    """All §9 measures for a fitted q = 2 model (time dim periodic) trained on the rings
    ``train_noisy``.  Test noise is drawn from ``random_state``."""
    rng = np.random.default_rng(random_state)
    t, p = model.time_dim_, 1 - model.time_dim_
    test = np.vstack(cylinder(TEST_HEIGHTS))
    test_noisy = test + rng.normal(0.0, NOISE, test.shape)
    rec = lambda Y: model.inverse_transform(model.transform(Y))  # noqa: E731
    train = np.vstack(train_noisy)
    out = {
        "nmse_test": nmse(test, rec(test)),
        "nmse_denoise": nmse(test, rec(test_noisy)),
        "bias": float(np.mean(1 - np.hypot(*rec(train)[:, :2].T))),
    }

    lat = model.latents_[:, p]
    _, seq = np.unique(model.sequence_ids_, return_inverse=True)
    within = [lat[seq == s].var() for s in range(seq.max() + 1)]
    out["param_variance"] = float(np.mean(within) / lat.var())

    params = np.linspace(lat.min(), lat.max(), len(TEST_HEIGHTS))
    times = np.pi * np.arange(n_time) / n_time
    nvar = []
    for v in params:
        X = np.empty((n_time, 2))
        X[:, t], X[:, p] = times, v
        Z = model.inverse_transform(X)
        nvar.append((np.hypot(Z[:, 0], Z[:, 1]).var() + Z[:, 2].var()) / Z.var(0).sum())
    out["ring_nvar_map"] = float(np.mean(nvar))

    proj = model.transform(test)[:, p].reshape(len(TEST_HEIGHTS), -1)
    out["ring_nvar_project"] = float(np.mean(proj.var(axis=1)) / proj.var())

    line_times = np.pi * np.arange(n_lines) / n_lines
    ncm_map = []
    for tt in line_times:
        X = np.empty((len(params), 2))
        X[:, t], X[:, p] = tt, params
        Z = model.inverse_transform(X)
        ncm_map.append(ncmse(np.arctan2(Z[:, 1], Z[:, 0]), 2 * np.pi))
    out["line_ncmse_map"] = float(np.mean(ncm_map))

    angles = 2 * np.pi * np.arange(n_lines) / n_lines
    ncm_proj = []
    for phi in angles:
        line = np.column_stack(
            [np.full(len(TEST_HEIGHTS), np.cos(phi)), np.full(len(TEST_HEIGHTS), np.sin(phi)), TEST_HEIGHTS]
        )
        ncm_proj.append(ncmse(model.transform(line)[:, t], np.pi))
    out["line_ncmse_project"] = float(np.mean(ncm_proj))
    return out


def write_csv_dir(folder, heights=TRAIN_HEIGHTS, noise=NOISE, random_state=0):
    """Write one CSV per noisy training ring (header ``t,x,y,z``; t = sample time in s)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for n, seq in enumerate(cylinder(heights, noise=noise, random_state=random_state)):
        t = np.arange(len(seq)) / 45.0
        np.savetxt(
            folder / f"ring_{n:02d}.csv",
            np.column_stack([t, seq]),
            delimiter=",",
            header="t,x,y,z",
            comments="",
            fmt="%.6f",
        )
    return folder


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description="write the toy-cylinder training rings as CSVs")
    ap.add_argument("folder", type=Path)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    print(write_csv_dir(a.folder, random_state=a.seed))
