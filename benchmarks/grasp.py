"""Benchmark of the grasp family: SOM training, PCP best-match search, grasp trials per minute.

Every figure comes with a baseline measured in the same run (medians over ``--repeats``):

- SOM training (25×25, online, thesis rule): the compiled epoch kernel vs. the same update written
  as a per-posture numpy loop;
- PCP best match over the 625 nodes: one vectorised query vs. a Python loop over nodes;
- one grasp trial (centred cylinder, tactile controller, disturbance test) vs. stepping the bare
  simulation for the same number of physics steps (the controller's and contact queries' overhead).

    python benchmarks/grasp.py [--repeats 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import statistics

import numpy as np
from threadpoolctl import threadpool_limits
from timing import median_time

from handflow.plugins.grasp.controller import ExperienceGraspController
from handflow.plugins.grasp.episode import CENTRED_POSE, EpisodeConfig, run_grasp
from handflow.plugins.grasp.hand_layout import hand_layout
from handflow.plugins.grasp.pcp import best_match_index
from handflow.plugins.grasp.som import SOM, decay
from handflow.plugins.hands.joints import HAND_MODELS
from handflow.plugins.simulator.scenes import GraspScene
from handflow.plugins.simulator.simulation import Simulation


def numpy_online_som(X, rows=25, cols=25, epochs=30, seed=0):
    """The baseline: eq. 4.8 per posture with numpy over nodes (what the compiled kernel replaces)."""
    som = SOM(rows=rows, cols=cols, epochs=1, random_state=seed)
    som.fit(X[:2])
    W = som.postures.copy()
    D2 = ((som.grid_[:, None] - som.grid_[None]) ** 2).sum(-1)
    rng = np.random.default_rng(seed)
    total = epochs * len(X)
    for e in range(epochs):
        for k, i in enumerate(rng.permutation(len(X))):
            tau = (e * len(X) + k) / (total - 1)
            eps, sig = decay(0.95, 0.05, tau), decay(6.0, 0.7, tau)
            bmu = np.argmin(((W - X[i]) ** 2).sum(1))
            W += (eps * np.exp(-D2[bmu] / (2 * sig**2)))[:, None] * (X[i] - W)
    return W


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    X = np.tanh(rng.uniform(-1, 1, (300, 2)) @ rng.normal(size=(2, 22)))
    out: dict = {}
    with threadpool_limits(1):
        SOM(rows=5, cols=5, epochs=1).fit(X[:10])  # compile the kernel outside the timing
        fast = median_time(lambda: SOM(epochs=30, random_state=0).fit(X), args.repeats)
        slow = median_time(lambda: numpy_online_som(X, epochs=30), args.repeats)
        out["som_train_25x25_300x22_30ep_s"] = {"compiled": fast, "numpy_loop": slow, "speedup": slow / fast}

        W = SOM(epochs=5, random_state=0).fit(X).postures
        mask = (rng.uniform(size=22) > 0.5).astype(float)
        q = X[3]
        n = 200
        vec = median_time(lambda: [best_match_index(W, q, mask) for _ in range(n)], args.repeats) / n
        loop = median_time(
            lambda: min(range(len(W)), key=lambda a: float(np.sum(mask * (W[a] - q) ** 2))), args.repeats
        )
        out["pcp_best_match_625_nodes_us"] = {"vectorised": vec * 1e6, "python_loop": loop * 1e6, "speedup": loop / vec}

        model, layout = HAND_MODELS["shadow"], hand_layout("shadow")
        ctl = ExperienceGraspController(layout, model.lower, model.upper)
        cfg = EpisodeConfig()
        steps = []

        def trial():
            r = run_grasp("cylinder", CENTRED_POSE, ctl, cfg, seed=0)
            steps.append(r.grasp_time_s + cfg.test.duration_s + cfg.settle_s)

        grasp = median_time(trial, args.repeats)
        n_steps = int(statistics.median(steps) * cfg.physics_hz)

        def bare():
            with Simulation(scene=GraspScene(object="cylinder")) as sim:
                sim.step(n_steps)

        physics = median_time(bare, args.repeats)
        out["grasp_trial_s"] = {
            "trial": grasp,
            "bare_physics_same_steps": physics,
            "overhead_ratio": grasp / physics,
            "grasps_per_minute": 60.0 / grasp,
            "physics_steps": n_steps,
        }
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        for key, vals in out.items():
            print(key, {k: round(v, 3) if isinstance(v, float) else v for k, v in vals.items()})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
