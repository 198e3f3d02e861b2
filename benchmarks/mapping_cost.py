"""Mapping cost per frame for the full chain raw → human model → ShadowHand.

Per-frame (one call per frame, as the nodes do) and batched (1000 frames per call) costs, plus the
node path (HumanHandMappingNode + ShadowHandMappingNode in NodeHarness, incl. message checks).
Baseline of the same run: a plain numpy linear map of 22 values per frame; ratios against it.
Medians over ``--repeats`` runs.

    python benchmarks/mapping_cost.py [--repeats 7] [--json]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from handflow.framework.messages import GloveFrame
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.glove.synthetic import SyntheticGlove
from handflow.plugins.mapping.nodes import HumanHandMappingNode, ShadowHandMappingNode
from handflow.plugins.mapping.robot import ShadowHandMapping


def _per_frame_us(fn, frames, repeats) -> float:
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for f in frames:
            fn(f)
        runs.append((time.perf_counter() - t0) / len(frames) * 1e6)
    return float(np.median(runs))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    glove = SyntheticGlove(noise=1.0)
    frames = glove.frames(np.linspace(0, 20, args.frames)).astype(float)
    human, shadow = glove.mapping, ShadowHandMapping()
    lo, gain = np.full(22, 40.0), np.full(22, 0.01)

    baseline = _per_frame_us(lambda s: lo + (s - lo) * gain, frames, args.repeats)
    chain = _per_frame_us(lambda s: shadow.map(human.map(s)), frames, args.repeats)
    human_only = _per_frame_us(human.map, frames, args.repeats)
    batch_runs = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        shadow.map(human.map(frames))
        batch_runs.append((time.perf_counter() - t0) / len(frames) * 1e6)
    batched = float(np.median(batch_runs))

    h = NodeHarness(HumanHandMappingNode, {}).setup()
    s = NodeHarness(ShadowHandMappingNode, {}).setup()
    msgs = [GloveFrame(sensors=f.astype(np.int64)) for f in frames]

    def node_path(msg):
        h.send("raw", msg)
        s.send("joints", h.published["joints"][-1])

    nodes = _per_frame_us(node_path, msgs, max(3, args.repeats // 2))

    result = {
        "frames": len(frames),
        "repeats": args.repeats,
        "baseline_linear22_us": round(baseline, 2),
        "raw_to_human_us": round(human_only, 2),
        "raw_to_shadow_us": round(chain, 2),
        "raw_to_shadow_batched_us": round(batched, 3),
        "node_path_us": round(nodes, 2),
        "ratio_chain_vs_baseline": round(chain / baseline, 1),
        "ratio_batched_vs_baseline": round(batched / baseline, 3),
        "ratio_nodes_vs_baseline": round(nodes / baseline, 1),
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for k, v in result.items():
            print(f"{k:28s} {v}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
