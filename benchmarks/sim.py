"""Simulator, camera and tracker figures: ``python benchmarks/sim.py [--json]``.

- ``physics_rtf``: real-time factor of 240 Hz physics, ShadowHand-like hand closed on a 2.5 cm cap
  (contacts active); baseline ``physics_rtf_empty``: the same hand with no scene objects;
- ``camera_fps_320`` / ``camera_fps_640``: TinyRenderer frames per second of the ball scene;
- ``tracker_fps``: BallTracker.update on a 320×240 rendered frame; baseline ``inrange_fps``: one
  bare ``cv2.inRange`` on the same (already HSV) image;
- ``tracker_err_median`` / ``tracker_err_p95``: error vs projected ground truth in normalised units
  (marks 2 apart) over random unoccluded ball placements;
- ``swaps_per_min``: the scripted open-loop ball motion (``BallSwapMotion``) in the ``balls`` scene,
  ``--swap-seconds`` of simulated time, median over seeds 0–2 (ground-truth swap counter);
- ``cap_flick_<r>cm`` / ``cap_turn_<r>cm``: cap rotation (rad, mean |·| per cycle over six cycles)
  in the non-turning phases (A open-back, D open) vs in close + rotate, with the demonstrator's
  release (fingertips uncurl first); baseline ``cap_flick_<r>cm_baseline``: the whole hand opens at
  once over phase D (the previous demonstrator).
Timing figures are the median of ``--repeats`` timed runs in this process.
"""

from __future__ import annotations

import argparse
import json

import cv2
import numpy as np
from timing import median_time

from handflow.plugins.demo.ball_swap import run_open_loop_swaps
from handflow.plugins.demo.cap_turning import CapTurningDemonstrator
from handflow.plugins.hands.joints import SHADOW
from handflow.plugins.simulator.bullet import pybullet as p
from handflow.plugins.simulator.metrics import count_swaps
from handflow.plugins.simulator.simulation import Simulation
from handflow.plugins.tracker.blobs import BALL_HSV, BallTracker, normalise_points

FLEX = [f"{f}J{k}" for f in ("FF", "MF", "RF", "LF") for k in (3, 2, 1)]


def physics_rtf(scene: str, steps: int, repeats: int) -> float:
    with Simulation("shadow", scene, {"radius": 0.025} if scene == "cap" else None) as sim:
        sim.set_targets(FLEX, [1.3] * len(FLEX))
        sim.step(240)
        return (steps / 240.0) / median_time(lambda: sim.step(steps), repeats)


def camera_fps(sim: Simulation, w: int, h: int, frames: int, repeats: int) -> float:
    return frames / median_time(lambda: [sim.render(w, h) for _ in range(frames)], repeats)


def tracker_accuracy(sim: Simulation, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    surface = -sim.scene.palm_thickness / 2 - sim.scene.ball_radius - 0.001
    cam, errors = sim.scene.camera(), []
    while len(errors) < n:
        local = np.c_[rng.uniform(-0.03, 0.03, 2), [surface] * 2, rng.uniform(0.05, 0.08, 2)]
        if np.linalg.norm(local[0] - local[1]) < 2 * sim.scene.ball_radius + 0.002:
            continue
        for ball, pos in zip(sim.scene.balls, sim.scene.palm_to_world(local)):
            p.resetBasePositionAndOrientation(ball, pos, [0, 0, 0, 1], physicsClientId=sim.client)
        res = BallTracker().update(sim.render(320, 240))
        marks = cam.project(sim.scene.mark_positions(), 320, 240)
        truth = normalise_points(cam.project(sim.scene.ball_positions(sim.client), 320, 240), marks[0], marks[1])
        if not res.balls_valid.all():
            errors.append(np.inf)
            continue
        d = np.linalg.norm(res.balls[:, None] - truth[None], axis=2)
        errors.extend(sorted([[d[0, 0], d[1, 1]], [d[0, 1], d[1, 0]]], key=sum)[0])
    return np.asarray(errors)


def swaps_per_min(seconds: float, seed: int) -> float:
    pts, _ = run_open_loop_swaps(seconds, seed)
    return 60.0 * count_swaps(pts[:, 0], pts[:, 1]) / seconds


def cap_rotation(demo: CapTurningDemonstrator, radius: float, cycles: int = 6, steps: int = 400) -> tuple[float, float]:
    """(mean |rotation| in the open phases, mean rotation in close + rotate) per cycle, rad."""
    rng = np.random.default_rng(0)
    flick, turn = [], []
    with Simulation("shadow", "cap", {"radius": radius}, seed=0) as sim:
        sim.set_targets(SHADOW.names, demo.targets(np.zeros(1), radius, demo.variation(rng))[0])
        sim.step(60)
        for _ in range(cycles):
            var = demo.variation(rng)
            phase = np.arange(steps) / steps
            targets, names = demo.targets(phase, radius, var), demo.phase_names(phase, var)
            done = {"turn": 0.0, "open": 0.0}
            for q, name in zip(targets, names):
                before = sim.scene_state()["cap_angle"]
                sim.set_targets(SHADOW.names, q)
                sim.step(1)
                done["turn" if name in ("close", "rotate") else "open"] += sim.scene_state()["cap_angle"] - before
            flick.append(abs(done["open"]))
            turn.append(done["turn"])
    return float(np.mean(flick)), float(np.mean(turn))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--swap-seconds", type=float, default=30.0, help="simulated seconds per swap run")
    args = ap.parse_args()
    out: dict[str, float] = {}
    out["physics_rtf"] = physics_rtf("cap", 480, args.repeats)
    out["physics_rtf_empty"] = physics_rtf("empty", 480, args.repeats)
    with Simulation("gifu", "balls", seed=0) as sim:
        sim.step(120)
        out["camera_fps_320"] = camera_fps(sim, 320, 240, 10, args.repeats)
        out["camera_fps_640"] = camera_fps(sim, 640, 480, 5, args.repeats)
        img = sim.render(320, 240)
        tracker = BallTracker()
        out["tracker_fps"] = 50 / median_time(lambda: [tracker.update(img) for _ in range(50)], args.repeats)
        hsv = cv2.cvtColor(img, cv2.COLOR_RGB2HSV)
        lo, hi = np.array(BALL_HSV.lower, np.uint8), np.array(BALL_HSV.upper, np.uint8)
        out["inrange_fps"] = 50 / median_time(lambda: [cv2.inRange(hsv, lo, hi) for _ in range(50)], args.repeats)
        err = tracker_accuracy(sim, 40)
    out["tracker_err_median"] = float(np.median(err))
    out["tracker_err_p95"] = float(np.percentile(err, 95))
    out["swaps_per_min"] = float(np.median([swaps_per_min(args.swap_seconds, seed) for seed in range(3)]))
    at_once = CapTurningDemonstrator(release_joints=tuple(SHADOW.names), release_fraction=0.99)
    for radius in (0.015, 0.02, 0.025, 0.03, 0.035):
        key = f"{radius * 100:.1f}cm"
        out[f"cap_flick_{key}"], out[f"cap_turn_{key}"] = cap_rotation(CapTurningDemonstrator(), radius)
        out[f"cap_flick_{key}_baseline"], out[f"cap_turn_{key}_baseline"] = cap_rotation(at_once, radius)
    out["ratio_physics_cap_vs_empty"] = out["physics_rtf"] / out["physics_rtf_empty"]
    out["ratio_camera_640_vs_320"] = out["camera_fps_640"] / out["camera_fps_320"]
    out["ratio_tracker_vs_inrange"] = out["tracker_fps"] / out["inrange_fps"]
    if args.json:
        print(json.dumps({k: round(v, 5) for k, v in out.items()}))
    else:
        for k, v in out.items():
            print(f"{k:28s} {v:12.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
