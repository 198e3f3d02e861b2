"""Grasp evaluation over a grid of object poses (docs/grasping.md; thesis 4.3).

For each object and pose of a :class:`~.grid.GraspGrid` (default :data:`~.grid.HARD_GRID`), three
controllers grasp from the same pre-grasp with the same disturbance seed:

- ``experience``: experience base = the object-specific SOM (thesis: object-specific 25×25 SOMs);
- ``no_experience``: the purely tactile closing heuristic;
- ``shared_som``: one SOM trained on the grasps of all objects (thesis: 30×30).

A grasp counts when it passes the :class:`~.stability.DisturbanceTest`; placements where the hand
already touches the object in the pre-grasp are skipped in every condition (thesis 4.3).  Shares are
pooled over all valid grasps of an object and, for ``overall``, of all objects.  Every evaluation
seed grasps the grid once (jittered poses, own disturbance directions: :meth:`~.grid.GraspGrid.trials`);
shares are pooled over seeds and reported per seed (``per_seed``, ``spread``).  Because every
condition grasps the same trials, the comparison with the tactile baseline is *paired*: the trials
an experience condition wins and loses against ``no_experience`` and the exact two-sided McNemar
test (:func:`sign_test`).  ``repeats`` > 1 runs every seed again with the closing speed γ scaled by
:func:`gamma_factors` (documented choice ``GAMMA_STEP``).  Also reported: the share of force-closure
grasps (wrench quality > 0) per condition and the grasps evaluated per minute of wall time; the
per-trial outcomes (``outcomes``) feed the success maps of :mod:`.plots`.
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
from .episode import EpisodeConfig, run_grasp
from .experience import ExperienceBase
from .grid import HARD_GRID, GraspGrid
from .hand_layout import hand_layout

CONDITIONS = ("experience", "no_experience", "shared_som")
COMPARED = ("experience", "shared_som")
"""The conditions compared pose by pose with the tactile baseline ``no_experience``."""
GAMMA_STEP = 0.02
"""Relative γ step between the repeats of an evaluation: factors 1, 1 − step, 1 + step, 1 − 2·step, …"""


def gamma_factors(repeats: int, step: float = GAMMA_STEP) -> list[float]:
    """The γ scale of each of ``repeats`` evaluation runs (the first is the configured γ)."""
    if repeats < 1:
        raise ValueError(f"repeats must be ≥ 1, got {repeats}")
    return [1.0 + step * (-(k + 1) // 2 if k % 2 else k // 2) for k in range(repeats)]


def experience_files(folder: Path, objects) -> dict[str, Path]:
    """The SOM files an evaluation needs: ``som_<object>.npz`` per object and ``som_shared.npz``."""
    return {**{obj: folder / f"som_{obj}.npz" for obj in objects}, "shared": folder / "som_shared.npz"}


def evaluate_grasping(
    experience_dir,
    grid: GraspGrid = HARD_GRID,
    objects=None,
    hand: str = "shadow",
    config: ControllerConfig = ControllerConfig(),
    episode: EpisodeConfig = EpisodeConfig(),
    progress: Callable[[str], None] | None = None,
    repeats: int = 1,
    seeds=(0,),
) -> dict:
    """Grasp ``grid`` (``objects``: a subset of its objects) for every seed and condition ``repeats``
    times; return the pooled result dict with ``per_seed`` results and their ``spread``."""
    factors = gamma_factors(repeats)
    objects = tuple(grid.objects if objects is None else objects)
    unknown = [o for o in objects if o not in grid.objects]
    if unknown or not objects or not seeds:
        raise ValueError(
            f"grid '{grid.name}' grasps {', '.join(grid.objects)}; got objects {list(objects)}, seeds {list(seeds)}"
        )
    files = experience_files(Path(experience_dir), objects)
    missing = [str(p) for p in files.values() if not p.exists()]
    if missing:
        raise FileNotFoundError(
            f"experience files missing: {', '.join(missing)}; create them with "
            f"`handflow grasp-experience --grid {grid.experience_grid} --out {experience_dir} --train-soms`"
        )
    layout = hand_layout(hand)
    model = HAND_MODELS[hand]
    episode = grid.episode(episode)
    shared = ExperienceBase.load(files["shared"])
    bases = {
        obj: {"experience": ExperienceBase.load(files[obj]), "no_experience": None, "shared_som": shared}
        for obj in objects
    }
    controllers = [
        (
            f,
            {
                obj: {
                    c: ExperienceGraspController(
                        layout, model.lower, model.upper, b, config.model_copy(update={"gamma": config.gamma * f})
                    )
                    for c, b in per.items()
                }
                for obj, per in bases.items()
            },
        )
        for f in factors
    ]
    outcomes: list[dict] = []
    t0 = time.perf_counter()
    for seed in seeds:
        for obj in objects:
            trials = grid.trials(obj, seed)
            for (f, ctl), (k, pose) in itertools.product(controllers, enumerate(trials)):
                row = {
                    "object": obj,
                    "seed": int(seed),
                    "gamma_factor": f,
                    "pose": grid.nominal(obj)[k].as_array().tolist(),
                }
                for cond, c in ctl[obj].items():
                    r = run_grasp(obj, pose, c, episode, seed=int(seed) * 100_003 + k, hand=hand)
                    row[cond] = (bool(r.stable), bool(r.quality > 0)) if r.valid else None
                outcomes.append(row)
            if progress is not None:
                rows = [o for o in outcomes if o["object"] == obj and o["seed"] == seed and o["no_experience"]]
                done = {c: sum(o[c][0] for o in rows) for c in CONDITIONS}
                progress(f"seed {seed}, {obj}: {len(rows)} valid trials, stable {done}")
    minutes = (time.perf_counter() - t0) / 60.0
    result = summarise(outcomes, objects)
    result["per_seed"] = {int(s): summarise([o for o in outcomes if o["seed"] == s], objects)["overall"] for s in seeds}
    result["spread"] = spread(result["per_seed"])
    result.update(
        grid=grid.name,
        seeds=[int(s) for s in seeds],
        repeats=repeats,
        gamma_factors=factors,
        lateral_friction=grid.lateral_friction,
        grasps_evaluated=len(outcomes) * len(CONDITIONS),
        grasps_per_minute=float(len(outcomes) * len(CONDITIONS) / minutes) if minutes > 0 else 0.0,
        outcomes=outcomes,
    )
    return result


def sign_test(wins: int, losses: int) -> dict:
    """Paired comparison with the tactile baseline on the same trials: trials won and lost and the exact
    two-sided McNemar p (= sign test on the discordant pairs: binomial, n = wins + losses, ½)."""
    p = binomtest(wins, wins + losses).pvalue if wins + losses else 1.0
    return {"wins": int(wins), "losses": int(losses), "p_sign": float(p)}


def summarise(outcomes: list[dict], objects) -> dict:
    """Shares per object and pooled ``overall`` from per-trial outcomes (``None``: invalid placement;
    else ``(stable, force closure)`` per condition); paired wins/losses of ``experience`` and
    ``shared_som`` against ``no_experience`` become McNemar tests."""
    out: dict = {}
    for key in [*objects, "overall"]:
        rows = [o for o in outcomes if o["no_experience"] is not None and key in (o["object"], "overall")]
        n = len(rows)
        out[key] = {c: float(np.mean([o[c][0] for o in rows])) if n else 0.0 for c in CONDITIONS}
        out[key]["force_closure"] = {c: float(np.mean([o[c][1] for o in rows])) if n else 0.0 for c in CONDITIONS}
        out[key]["n_valid"] = n
        out[key]["paired"] = {
            c: sign_test(
                sum(o[c][0] > o["no_experience"][0] for o in rows), sum(o[c][0] < o["no_experience"][0] for o in rows)
            )
            for c in COMPARED
        }
    out["experience_gain"] = out["overall"]["experience"] - out["overall"]["no_experience"]
    return out


def spread(per_seed: dict) -> dict:
    """Mean, standard deviation, minimum and maximum over seeds of the overall shares and the gain."""
    values = {c: [r[c] for r in per_seed.values()] for c in CONDITIONS}
    values["experience_gain"] = [r["experience"] - r["no_experience"] for r in per_seed.values()]
    return {
        k: {"mean": float(np.mean(v)), "std": float(np.std(v)), "min": float(np.min(v)), "max": float(np.max(v))}
        for k, v in values.items()
    }
