"""Speed benchmark of Structured UKR.

* seconds for 600 RPROP steps: N = 1800, d = 20, q = 1 (periodic) and N = 1200, d = 24, q = 2
  (periodic + Gaussian); latents initialised from given values so only optimisation is timed;
* median latency of one ``transform`` (model N = 300, d = 2, q = 1) and of a batch of 1000;
* achieved GFLOP/s of one objective+gradient evaluation (N = 1800, d = 20, q = 1) and its ratio
  to a plain numpy matmul (N×N)·(N×d) measured in the same run.  Flops counted for this
  implementation (objective.py): exponent GEMM 2N²·3q, exp N², and the two N×N GEMMs
  K·[Y, Y∘P, P, 1] = 2N²(d + 2dq + 2q + 1) and K·[E∘Q, c∘Q] = 2N²(2dq + 2q)
  (du/dδ has rank 2 per dimension).  The machine is shared: the 1-min load average is printed.
* the neighbour-list path at scale (``ukr_scale.py``: ``sparse_vs_dense_objective_rel``,
  ``sparse_vs_dense_time_ratio``, ``sparse_n20000_s``, ``sparse_peak_mb``, ``scaling_exponent``
  and more); ``--part dense`` or ``--part scale`` runs one half.

    python benchmarks/ukr_speed.py [--json] [--repeats 3] [--part all|dense|scale]
"""

from __future__ import annotations

import argparse
import json
import os

import numpy as np
import ukr_scale
from timing import median_time

from handflow.plugins.manifold import StructuredUKR
from handflow.plugins.manifold.objective import Objective, SequenceLayout
from handflow.plugins.manifold.validation import parse_latent

PERIODIC = {"kernel": "periodic", "beta": 12.0, "time": True}


def periodic_data(n_seq, n_per, d, q, seed=0):
    """Sequences on a random smooth closed curve (q = 1) or tube (q = 2) in R^d + noise."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((8, d)) / 2
    seqs, lat = [], []
    for s in range(n_seq):
        t = np.pi * (np.arange(n_per) / n_per + rng.uniform())
        h = np.full(n_per, s / n_seq)
        feats = np.c_[
            np.cos(2 * t), np.sin(2 * t), np.cos(4 * t), np.sin(4 * t), np.sin(6 * t), h, h * np.cos(2 * t), h**2
        ]
        if q == 1:
            feats[:, 5:] = 0
        seqs.append(feats @ A + rng.normal(0, 0.02, (n_per, d)))
        lat.append(np.c_[np.mod(t, np.pi), h][:, :q])
    return seqs, np.vstack(lat) + rng.normal(0, 0.01, (n_seq * n_per, q))


def train_seconds(n_seq, n_per, d, q, repeats):
    seqs, X0 = periodic_data(n_seq, n_per, d, q)
    latent = [PERIODIC, {"kernel": "gaussian", "beta": 4.0}][:q]
    return median_time(lambda: StructuredUKR(latent=latent, n_steps=600, init=X0).fit(seqs), repeats)


def projection_ms(repeats):
    seqs, X0 = periodic_data(6, 50, 2, 1, seed=1)
    model = StructuredUKR(latent=[PERIODIC], n_steps=100, init=X0).fit(seqs)
    rng = np.random.default_rng(2)
    Y = np.vstack(seqs)[rng.integers(0, 300, 1000)] + rng.normal(0, 0.05, (1000, 2))
    model.transform(Y[0])
    singles = [median_time(lambda y=y: model.transform(y), 1) for y in Y[: max(200, repeats)]]
    batch = median_time(lambda: model.transform(Y), max(10, repeats))
    return 1e3 * float(np.median(singles)), 1e3 * batch


def gflops(repeats, N=1800, d=20, q=1):
    seqs, X = periodic_data(N // 45, 45, d, q)
    kernel, t = parse_latent([PERIODIC])
    obj = Objective(
        np.vstack(seqs),
        kernel,
        SequenceLayout(np.repeat(np.arange(N // 45), 45)),
        time_dim=t,
        lambda_cseq=1.0,
        lambda_pvar=1.0,
    )
    obj(X)
    sec = median_time(lambda: obj(X), max(20, repeats))
    flops = N * N * (6 * q + 1 + 2 * (d + 2 * d * q + 2 * q + 1) + 2 * (2 * d * q + 2 * q))
    A, B = np.random.default_rng(0).standard_normal((N, N)), np.ones((N, d))
    A @ B
    mm = 2 * N * N * d / median_time(lambda: A @ B, max(20, repeats)) / 1e9
    return flops / sec / 1e9, mm, sec * 1e3


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--repeats", type=int, default=3, help="training repeats (median)")
    ap.add_argument("--part", choices=("all", "dense", "scale"), default="all", help="which measurements")
    ap.add_argument("--data", default=ukr_scale.DEFAULT_DATA, help="real recordings for the held-out comparison")
    a = ap.parse_args()
    res = dense_suite(a.repeats) if a.part != "scale" else {}
    if a.part != "dense":
        res |= ukr_scale.measure(a.repeats, a.data)
    if a.json:
        print(json.dumps(res))
        return
    for key, value in res.items():
        print(f"{key}: {value}")
    print(f"load average (1 min) at the end: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")


def dense_suite(repeats):
    gf, mm, eval_ms = gflops(repeats)
    single, batch = projection_ms(repeats)
    return {
        "train_seconds_n1800": train_seconds(40, 45, 20, 1, repeats),
        "train_seconds_n1200": train_seconds(24, 50, 24, 2, repeats),
        "project_single_ms": single,
        "project_batch1000_ms": batch,
        "gflops": gf,
        "gflops_ratio_to_matmul": gf / mm,
        "objective_eval_ms": eval_ms,
    }


if __name__ == "__main__":
    main()
