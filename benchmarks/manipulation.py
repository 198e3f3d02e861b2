"""Manipulation benchmark: control-loop cost and manifold build cost.

* control-loop latency, observation → command, through :class:`ClosedLoopNode` code (partial
  projection with both ball assignments + k-step plan + publish) on the project's ball-swap
  manifold; baseline in the same run: one ``f(x)`` evaluation of the same manifold (what the
  open-loop controller does per tick).  Medians and p99 in ms, ratio of medians;
* seconds to build the cap manifold by construction (configs/train/cap_construction.yaml) vs
  by learning (cap_learning.yaml, 600 steps) on the same recording; ``--no-training`` skips it.

    python benchmarks/manipulation.py [--json] [--n 500] [--no-training]

The machine is shared: the 1-min load average is printed with the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from handflow.framework.messages import Points2D
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.manipulation.cli import CONFIGS_MODELS, TRAIN_CONFIGS, ensure_manifold
from handflow.plugins.manipulation.nodes import ClosedLoopNode
from handflow.plugins.manipulation.training import load_config, train_manifold


def _ms(samples):
    ms = np.asarray(samples) * 1e3
    return {"median": float(np.median(ms)), "p99": float(np.percentile(ms, 99))}


def latency(path, n, seed=0):
    h = NodeHarness(ClosedLoopNode, {"manifold": str(path), "k": 5}).setup()
    man = h.node.manifold
    rng = np.random.default_rng(seed)
    rows = rng.integers(0, len(man.model.Y_), n)
    obs = man.model.Y_[rows][:, man.ball_index].reshape(n, 2, 2)
    lat = man.model.latents_[rows]
    loop, f_only = [], []
    for pts, x in zip(obs, lat):
        msg = Points2D(points=pts[rng.permutation(2)], valid=[True, True], ids=[0, 1])
        t0 = time.perf_counter()
        h.send("balls", msg)
        loop.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        man.posture(x)
        f_only.append(time.perf_counter() - t0)
    out = {"closed_loop_ms": _ms(loop), "f_baseline_ms": _ms(f_only)}
    out["ratio_median"] = out["closed_loop_ms"]["median"] / out["f_baseline_ms"]["median"]
    return out


def build_times():
    out = {}
    for name in ("cap_construction.yaml", "cap_learning.yaml"):
        cfg = load_config(TRAIN_CONFIGS / name)
        t0 = time.perf_counter()
        train_manifold(cfg)
        out[name] = time.perf_counter() - t0
    out["ratio_learning_over_construction"] = out["cap_learning.yaml"] / out["cap_construction.yaml"]
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--n", type=int, default=500, help="observations for the latency figures")
    ap.add_argument("--no-training", action="store_true", help="skip the build-time comparison")
    args = ap.parse_args()
    path = ensure_manifold("balls", CONFIGS_MODELS, say=lambda line: None)
    result = {"load_avg_1min": os.getloadavg()[0], "latency": latency(path, args.n)}
    if not args.no_training:
        result["build_s"] = build_times()
    if args.json:
        print(json.dumps(result, indent=2))
        return
    lat = result["latency"]
    print(f"load average (1 min): {result['load_avg_1min']:.2f}")
    print(
        f"closed loop obs→command: median {lat['closed_loop_ms']['median']:.3f} ms, "
        f"p99 {lat['closed_loop_ms']['p99']:.3f} ms"
    )
    print(
        f"baseline f(x):           median {lat['f_baseline_ms']['median']:.3f} ms, "
        f"p99 {lat['f_baseline_ms']['p99']:.3f} ms   (ratio of medians {lat['ratio_median']:.1f}×)"
    )
    if "build_s" in result:
        b = result["build_s"]
        print(
            f"cap manifold build: construction {b['cap_construction.yaml']:.1f} s, learning "
            f"{b['cap_learning.yaml']:.1f} s (ratio {b['ratio_learning_over_construction']:.2f}×)"
        )


if __name__ == "__main__":
    main()
