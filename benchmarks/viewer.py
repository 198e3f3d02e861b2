"""Cost of the 3D-view outputs per simulator tick (docs/benchmarks.md, "3D view").

Per tick the simulator node builds the hand's TF tree from pybullet's link poses and the scene's
markers and packs both as CDR (docs/foxglove.md); ``simulator.robot_state`` runs forward
kinematics of the human hand.  Baseline, measured in the same run: the physics steps of one tick
(``physics_hz / rate_hz`` = 8 steps at 240 Hz physics and 30 Hz ticks, as in the flagship).

    python benchmarks/viewer.py --repeats 300 --json
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

from handflow.framework.wire import pack
from handflow.plugins.hands.joints import HUMAN
from handflow.plugins.simulator.hand_geometry import build_skeleton
from handflow.plugins.simulator.kinematics import HandKinematics
from handflow.plugins.simulator.simulation import Simulation
from handflow.plugins.simulator.viewer import scene_markers, simulated_hand_transforms


def median_ms(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e3


def tick_view(sim: Simulation) -> None:
    for msg in (simulated_hand_transforms(sim, "sim/"), scene_markers(sim)):
        msg.header.source = "sim"
        pack(msg)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=300)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    out = {}
    for hand, scene in (("shadow", "cap"), ("gifu", "balls")):
        with Simulation(hand=hand, scene=scene) as sim:
            physics = median_ms(lambda: sim.step(8), args.repeats)
            view = median_ms(lambda: tick_view(sim), args.repeats)
        out[f"{hand}_{scene}"] = {"physics_tick_ms": physics, "view_tick_ms": view, "ratio": view / physics}
    kin = HandKinematics(build_skeleton("human"), "human/")
    q = np.random.default_rng(0).uniform(HUMAN.lower, HUMAN.upper)
    out["human_fk_ms"] = median_ms(lambda: kin.transforms(HUMAN.names, q), args.repeats)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        for key, value in out.items():
            print(key, value)


if __name__ == "__main__":
    main()
