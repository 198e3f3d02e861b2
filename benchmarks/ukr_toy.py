"""Toy-cylinder benchmark of Structured UKR (docs/training.md).

Protocol: 10 noisy training sets (6 rings, σ = 0.1), q = 2 (periodic time β1 = 12, Gaussian
height β2 = 4), LOO-CV, Isomap (K = 10) + atan2* init, 500 RPROP steps; all §9 error
measures as mean and std over the runs; once with λ_cseq = λ_pvar = 1 ("structured") and
once with λ = 0 ("ablation").  ``--compare-optimizers`` adds RPROP vs L-BFGS convergence.

    python benchmarks/ukr_toy.py [--json] [--runs 10] [--steps 500] [--compare-optimizers]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from handflow.plugins.manifold import StructuredUKR, toy

LATENT = [{"kernel": "periodic", "beta": 12.0, "time": True}, {"kernel": "gaussian", "beta": 4.0}]
MEASURES = (
    "nmse_test",
    "nmse_denoise",
    "bias",
    "param_variance",
    "ring_nvar_map",
    "ring_nvar_project",
    "line_ncmse_map",
    "line_ncmse_project",
)


def model(lam, steps, optimizer="rprop"):
    return StructuredUKR(
        latent=LATENT,
        lambda_cseq=lam,
        lambda_pvar=lam,
        n_steps=steps,
        optimizer=optimizer,
        isomap_neighbors=(10,),
        random_state=0,
    )


def protocol(lam, runs, steps):
    t0 = time.perf_counter()
    rows = []
    for run in range(runs):
        train = toy.cylinder(toy.TRAIN_HEIGHTS, noise=toy.NOISE, random_state=100 + run)
        m = model(lam, steps).fit(train)
        rows.append(toy.evaluate(m, train, random_state=200 + run))
    out = {k: [float(np.mean([r[k] for r in rows])), float(np.std([r[k] for r in rows]))] for k in MEASURES}
    out["seconds"] = time.perf_counter() - t0
    return out


def compare_optimizers(runs, steps, checkpoints=(10, 50, 100, 200, 500)):
    """Objective after n steps/iterations, function evaluations and seconds per optimiser."""
    out = {}
    for opt in ("rprop", "lbfgs"):
        curves, evals, secs = [], [], []
        for run in range(runs):
            train = toy.cylinder(toy.TRAIN_HEIGHTS, noise=toy.NOISE, random_state=100 + run)
            t0 = time.perf_counter()
            m = model(1.0, steps, opt).fit(train)
            secs.append(time.perf_counter() - t0)
            h = np.minimum.accumulate(m.history_)
            curves.append([float(h[min(c, len(h) - 1)]) for c in checkpoints if c <= steps])
            evals.append(m.n_evaluations_)
        out[opt] = {
            "best_objective_at_step": dict(zip(map(str, checkpoints), np.mean(curves, 0).tolist())),
            "evaluations": float(np.mean(evals)),
            "seconds": float(np.mean(secs)),
        }
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--compare-optimizers", action="store_true")
    a = ap.parse_args()
    res = {"structured": protocol(1.0, a.runs, a.steps), "ablation": protocol(0.0, a.runs, a.steps)}
    if a.compare_optimizers:
        res["optimizers"] = compare_optimizers(min(a.runs, 5), a.steps)
    if a.json:
        print(json.dumps(res))
        return
    print(f"toy cylinder, {a.runs} runs x {a.steps} steps; mean ± std")
    print(f"{'measure':22s}{'λ = 1, 1':>24s}{'λ = 0 (ablation)':>24s}")
    for k in MEASURES:
        s, b = res["structured"][k], res["ablation"][k]
        print(f"{k:22s}{s[0]:>14.5f} ± {s[1]:<7.5f}{b[0]:>14.5f} ± {b[1]:<7.5f}")
    print(f"{'seconds':22s}{res['structured']['seconds']:>14.1f}{res['ablation']['seconds']:>24.1f}")
    for opt, r in res.get("optimizers", {}).items():
        print(
            f"{opt}: best objective at step {r['best_objective_at_step']}, "
            f"{r['evaluations']:.0f} evaluations, {r['seconds']:.2f} s"
        )


if __name__ == "__main__":
    main()
