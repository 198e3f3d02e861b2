"""Grasp evaluation over a grid of object poses (docs/grasping.md; thesis 4.3).

For each object and grid pose, three controllers grasp from the same pre-grasp with the same
disturbance seed:

- ``experience``: experience base = the object-specific SOM (thesis: object-specific 25×25 SOMs);
- ``no_experience``: the purely tactile closing heuristic;
- ``shared_som``: one SOM trained on the grasps of all objects (thesis: 30×30).

A grasp counts when it passes the :class:`~.stability.DisturbanceTest`; placements where the hand
already touches the object in the pre-grasp are skipped in every condition (thesis 4.3).  Rotations
about the vertical are evaluated for the box and the lying cylinder; the sphere is symmetric (thesis:
symmetric rotations ignored).  Shares are pooled over all valid grasps of an object
and, for ``overall``, of all objects.  Because every condition grasps the same poses with the same
seeds, the comparison with the tactile baseline is also reported *paired*: the poses an experience
condition wins and loses against ``no_experience`` and the two-sided sign-test p-value
(:func:`sign_test`).  ``repeats`` > 1 runs the whole grid again with the closing speed γ scaled by
:func:`gamma_factors` (documented choice ``GAMMA_STEP``) and pools all runs: even the damped grasp
(:mod:`.episode`) is sensitive — a 2 % change of γ flips about 9 % of the outcomes, most of them
sphere grasps — so one run cannot resolve differences of a few points.  Also reported: the share of
force-closure grasps (wrench quality > 0) per condition and the grasps evaluated per minute of wall
time.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.stats import binomtest

from handflow.plugins.hands.joints import HAND_MODELS

from .controller import ControllerConfig, ExperienceGraspController
from .episode import EpisodeConfig, GraspPose, run_grasp
from .experience import ExperienceBase
from .hand_layout import hand_layout

OBJECTS = ("box", "cylinder", "sphere")
CONDITIONS = ("experience", "no_experience", "shared_som")
COMPARED = ("experience", "shared_som")
"""The conditions compared pose by pose with the tactile baseline ``no_experience``."""
SYMMETRIC_ABOUT_VERTICAL = ("sphere",)

FULL_GRID = {
    "x": (0.02, 0.03, 0.04, 0.05),
    "y": (-0.012, 0.0, 0.012),
    "gap": (0.005, 0.015, 0.025),
    "yaw_deg": (-30.0, 0.0, 30.0),
}
"""Full grid: offsets along the fingers / across the palm (m), gap below the palm (m), yaw (deg).
The object centre lies 8–11 cm from the wrist, under the knuckles and proximal finger segments."""
QUICK_GRID = {"x": (0.02, 0.035, 0.05), "y": (0.0,), "gap": (0.005, 0.02), "yaw_deg": (-30.0, 30.0)}
"""Coarse grid of ``--quick`` (under 2 minutes on the CI machine)."""


GAMMA_STEP = 0.02
"""Relative γ step between the repeats of an evaluation: factors 1, 1 − step, 1 + step, 1 − 2·step, …"""


def gamma_factors(repeats: int, step: float = GAMMA_STEP) -> list[float]:
    """The γ scale of each of ``repeats`` evaluation runs (the first is the configured γ)."""
    if repeats < 1:
        raise ValueError(f"repeats must be ≥ 1, got {repeats}")
    return [1.0 + step * (-(k + 1) // 2 if k % 2 else k // 2) for k in range(repeats)]


def grid_poses(obj: str, grid: dict) -> list[GraspPose]:
    yaws = (0.0,) if obj in SYMMETRIC_ABOUT_VERTICAL else grid["yaw_deg"]
    return [GraspPose(x, y, gap, yaw) for x, y, gap, yaw in itertools.product(grid["x"], grid["y"], grid["gap"], yaws)]


def experience_files(folder: Path) -> dict[str, Path]:
    """The SOM files an evaluation needs: ``som_<object>.npz`` per object and ``som_shared.npz``."""
    return {**{obj: folder / f"som_{obj}.npz" for obj in OBJECTS}, "shared": folder / "som_shared.npz"}


def evaluate_grasping(
    experience_dir,
    grid: dict = FULL_GRID,
    objects=OBJECTS,
    hand: str = "shadow",
    config: ControllerConfig = ControllerConfig(),
    episode: EpisodeConfig = EpisodeConfig(),
    progress: Callable[[str], None] | None = None,
    repeats: int = 1,
) -> dict:
    """Run the grid for every object and condition ``repeats`` times; return the pooled result dict."""
    factors = gamma_factors(repeats)
    files = experience_files(Path(experience_dir))
    missing = [str(p) for key, p in files.items() if (key in objects or key == "shared") and not p.exists()]
    if missing:
        raise FileNotFoundError(
            f"experience files missing: {', '.join(missing)}; create them with "
            f"`handflow grasp-experience --out {experience_dir} --train-soms`"
        )
    layout = hand_layout(hand)
    model = HAND_MODELS[hand]
    shared = ExperienceBase.load(files["shared"])
    counts = {obj: {c: [0, 0, 0] for c in CONDITIONS} for obj in objects}  # stable, force closure, valid
    paired = {obj: {c: [0, 0] for c in COMPARED} for obj in objects}  # poses won, lost vs no_experience
    t0 = time.perf_counter()
    n_run = 0
    for obj in objects:
        bases = {"experience": ExperienceBase.load(files[obj]), "no_experience": None, "shared_som": shared}
        poses = grid_poses(obj, grid)
        runs = [
            (
                f,
                {
                    c: ExperienceGraspController(
                        layout, model.lower, model.upper, b, config.model_copy(update={"gamma": config.gamma * f})
                    )
                    for c, b in bases.items()
                },
            )
            for f in factors
        ]
        for (f, controllers), (k, pose) in itertools.product(runs, enumerate(poses)):
            stable = {}
            for cond, ctl in controllers.items():
                r = run_grasp(obj, pose, ctl, episode, seed=k, hand=hand)
                n_run += 1
                if r.valid:
                    c = counts[obj][cond]
                    c[0] += r.stable
                    c[1] += r.quality > 0
                    c[2] += 1
                    stable[cond] = r.stable
            base = stable.get("no_experience")
            for cond, won_lost in paired[obj].items():
                if cond in stable and base is not None:
                    won_lost[0] += stable[cond] > base
                    won_lost[1] += stable[cond] < base
            if progress is not None:
                done = {c: counts[obj][c][0] for c in CONDITIONS}
                progress(f"{obj} (γ × {f:g}): pose {k + 1}/{len(poses)}, stable so far {done}")
    minutes = (time.perf_counter() - t0) / 60.0
    return {**summarise(counts, paired, n_run, minutes), "repeats": repeats, "gamma_factors": factors}


def sign_test(wins: int, losses: int) -> dict:
    """Paired comparison with the tactile baseline on the same poses: poses won and lost, two-sided sign-test p."""
    p = binomtest(wins, wins + losses).pvalue if wins + losses else 1.0
    return {"wins": int(wins), "losses": int(losses), "p_sign": float(p)}


def summarise(counts: dict, paired: dict, n_run: int, minutes: float) -> dict:
    """Shares per object and pooled ``overall`` from [stable, force closure, valid] counts; paired
    [wins, losses] of ``experience`` and ``shared_som`` against ``no_experience`` become sign tests."""

    def share(a, n):
        return float(a / n) if n else 0.0

    out: dict = {}
    pooled = {c: np.zeros(3) for c in CONDITIONS}
    for obj, per in counts.items():
        out[obj] = {c: share(per[c][0], per[c][2]) for c in CONDITIONS}
        out[obj]["force_closure"] = {c: share(per[c][1], per[c][2]) for c in CONDITIONS}
        out[obj]["n_valid"] = int(per[CONDITIONS[0]][2])
        out[obj]["paired"] = {c: sign_test(*wl) for c, wl in paired[obj].items()}
        for c in CONDITIONS:
            pooled[c] += per[c]
    out["overall"] = {c: share(pooled[c][0], pooled[c][2]) for c in CONDITIONS}
    out["overall"]["force_closure"] = {c: share(pooled[c][1], pooled[c][2]) for c in CONDITIONS}
    out["overall"]["n_valid"] = int(pooled[CONDITIONS[0]][2])
    out["overall"]["paired"] = {c: sign_test(*np.sum([paired[o][c] for o in paired], axis=0)) for c in COMPARED}
    out["experience_gain"] = out["overall"]["experience"] - out["overall"]["no_experience"]
    out["grasps_evaluated"] = n_run
    out["grasps_per_minute"] = float(n_run / minutes) if minutes > 0 else 0.0
    return out
