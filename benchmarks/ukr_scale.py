"""Structured UKR at scale: the neighbour-list path (plugins/manifold/sparse.py) vs dense.

* N = 1800, d = 20: 300 RPROP steps with compact kernels (periodic_quartic time + quartic),
  sparse and dense from the same given latents; final objective relative difference and the
  ratio of median training times (dense is the baseline, same kernels, same latents);
* N = 20 000, d = 20, 300 steps in a fresh subprocess: wall and CPU seconds and peak RSS
  (``resource.getrusage(RUSAGE_SELF).ru_maxrss``, imports included);
* seconds per step for N = 2 000 … 50 000 at constant latent density (sequences of 50 points
  stacked along the second latent coordinate at a fixed spacing, fixed β): fitted exponent of
  process CPU time per step (wall time on a shared machine also counts waiting);
* float32 vs float64 objective and gradient at N = 20 000;
* real data (``--data`` gesture_phases.npz, all 7 recordings, 9 901 frames, 18 dims — no shared
  set has 20 000 frames): every 10th frame held out; sparse fit on all other frames vs a dense
  fit on an evenly spaced 2 000-frame subset, both isomap init + 100 steps; held-out mean
  normalised reconstruction error (``StructuredUKR.score``).

    nice -n 5 python benchmarks/ukr_scale.py [--json] [--data /work/shared/data/gesture_phases.npz]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from timing import median_time

from handflow.plugins.manifold import StructuredUKR
from handflow.plugins.manifold.objective import SequenceLayout
from handflow.plugins.manifold.sparse import SparseObjective
from handflow.plugins.manifold.validation import parse_latent

LATENT = [{"kernel": "periodic_quartic", "beta": 8.0, "time": True}, {"kernel": "quartic", "beta": 4.0}]
DEFAULT_DATA = "/work/shared/data/gesture_phases.npz"
N_PER, SPACING = 50, 0.05  # points per sequence; second-coordinate spacing of sequences


def scale_data(N, d=20, seed=0):
    """N points of N/50 closed sequences on a smooth 2-D sheet in R^d, latents at constant density."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((8, d)) / 2
    n_seq = N // N_PER
    t = np.tile(np.pi * np.arange(N_PER) / N_PER, n_seq) + np.repeat(rng.uniform(0, np.pi, n_seq), N_PER)
    h = np.repeat(SPACING * np.arange(n_seq), N_PER)
    c, s = np.cos(2 * t), np.sin(2 * t)
    Y = np.c_[c, s, np.cos(4 * t), np.sin(4 * t), np.sin(h), np.cos(h), np.sin(h) * c, np.cos(h) * s] @ A
    Y += rng.normal(0, 0.02, Y.shape)
    X0 = np.c_[np.mod(t, np.pi), h] + rng.normal(0, 0.01, (N, 2))
    return Y, np.repeat(np.arange(n_seq), N_PER), X0


def fit(N, steps, sparse, d=20):
    Y, ids, X0 = scale_data(N, d)
    return StructuredUKR(latent=LATENT, n_steps=steps, init=X0, sparse=sparse).fit(Y, ids)


def n1800(repeats, steps=300):
    times, values = {}, {}
    for mode in (True, False):
        runs = []
        for _ in range(repeats):
            start, cpu = time.perf_counter(), time.process_time()
            values[mode] = fit(1800, steps, mode).objective_
            runs.append((time.perf_counter() - start, time.process_time() - cpu))
        times[mode] = np.median(runs, axis=0)
    return {
        "sparse_vs_dense_objective_rel": abs(values[True] - values[False]) / abs(values[False]),
        "sparse_vs_dense_time_ratio": times[True][0] / times[False][0],
        "sparse_vs_dense_cpu_ratio": times[True][1] / times[False][1],
        "n1800_sparse_s": times[True][0],
        "n1800_dense_s": times[False][0],
        "n1800_sparse_cpu_s": times[True][1],
        "n1800_dense_cpu_s": times[False][1],
    }


def big_run_child(N, steps):
    start, cpu = time.perf_counter(), time.process_time()
    fit(N, steps, True)
    sec, cpu = time.perf_counter() - start, time.process_time() - cpu
    print(json.dumps({"s": sec, "cpu_s": cpu, "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))


def big_run(N=20000, steps=300):
    code = f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); import ukr_scale; "
    code += f"ukr_scale.big_run_child({N}, {steps})"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    r = json.loads(out.strip().splitlines()[-1])
    return {"sparse_n20000_s": r["s"], "sparse_n20000_cpu_s": r["cpu_s"], "sparse_peak_mb": r["peak_mb"]}


def scaling(sizes=(2000, 5000, 10000, 20000, 50000), steps=20, repeats=3):
    per_step = []  # process CPU seconds per step (the machine is shared: wall time mixes in waiting)
    for n in sizes:
        runs = []
        for _ in range(repeats):
            cpu = time.process_time()
            fit(n, steps, True)
            runs.append((time.process_time() - cpu) / steps)
        per_step.append(float(np.median(runs)))
    slope = float(np.polyfit(np.log(sizes), np.log(per_step), 1)[0])
    return {"scaling_exponent": slope, "scaling_sizes": list(sizes), "scaling_step_cpu_s": per_step}


def float32_error(N=20000):
    Y, ids, X = scale_data(N)
    kernel, t = parse_latent(LATENT)
    args = dict(time_dim=t, lambda_cseq=1.0, lambda_pvar=1.0)
    obj = {dt: SparseObjective(Y, kernel, SequenceLayout(ids), dtype=dt, **args) for dt in (np.float64, np.float32)}
    (v1, g1), (v2, g2) = (obj[dt].reconstruction(X) for dt in (np.float64, np.float32))
    t64 = median_time(lambda: obj[np.float64](X), 5)
    t32 = median_time(lambda: obj[np.float32](X), 5)
    return {
        "float32_objective_rel": abs(v2 - v1) / abs(v1),
        "float32_gradient_rel": float(np.abs(g2 - g1).max() / np.abs(g1).max()),
        "float32_time_ratio": t32 / t64,
        "float32_note": "reconstruction term R_cv only (penalties dominate the total)",
        "mean_neighbours_n20000": obj[np.float64].pairs.mean_neighbours,
    }


def held_out(path, steps=100, subset=2000):
    data = np.load(path)
    recs = sorted(k for k in data.files if k.startswith("X_"))
    Y = np.vstack([data[k] for k in recs])
    ids = np.concatenate([np.full(len(data[k]), i) for i, k in enumerate(recs)])
    Y = (Y - Y.mean(axis=0)) / Y.std(axis=0)
    test = np.zeros(len(Y), bool)
    test[::10] = True
    Ytr, idtr = Y[~test], ids[~test]
    latent = [{"kernel": "quartic", "beta": 1.0}, {"kernel": "quartic", "beta": 1.0}]
    common = dict(latent=latent, lambda_cseq=0.0, lambda_pvar=0.0, n_steps=steps, isomap_neighbors=(10,))
    sub = np.linspace(0, len(Ytr) - 1, subset).astype(int)
    res = {}
    for name, (Yf, idf, sparse) in {
        "full_sparse": (Ytr, idtr, True),
        "subset_dense": (Ytr[sub], idtr[sub], False),
    }.items():
        start = time.perf_counter()
        m = StructuredUKR(sparse=sparse, **common).fit(Yf, idf)
        res[f"heldout_{name}_fit_s"] = time.perf_counter() - start
        res[f"heldout_{name}_error"] = -m.score(Y[test])
        res[f"heldout_{name}_n"] = len(Yf)
    return res


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--repeats", type=int, default=3, help="timing repeats (median)")
    ap.add_argument("--data", type=Path, default=Path(DEFAULT_DATA), help="real recordings (held-out part)")
    a = ap.parse_args()
    res = measure(a.repeats, a.data)
    if a.json:
        print(json.dumps(res))
        return
    for k, v in res.items():
        print(f"{k}: {v}")


def measure(repeats=3, data=None):
    res = n1800(repeats) | big_run() | scaling(repeats=repeats) | float32_error()
    if data is not None and Path(data).is_file():
        res |= held_out(data)
    res["load_average_1min"] = os.getloadavg()[0]
    return res


if __name__ == "__main__":
    main()
