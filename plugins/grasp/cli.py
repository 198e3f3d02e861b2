"""Commands ``grasp-experience``, ``grasp-som`` and ``evaluate grasping`` (docs/grasping.md)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from threadpoolctl import threadpool_limits

from handflow.framework.files.resources import shipped

from .evaluation import evaluate_grasping
from .experience import GraspDataset
from .generation import FIXED_PREGRASP_RANGES, PREGRASP_RANGES, generate_experience
from .grid import GRIDS, HARD_GRID, QUICK_HARD_GRID, THESIS_GRID, GraspGrid
from .plots import plot_node_postures, plot_success_maps, plot_u_matrix
from .som import load_som, save_som
from .training import train_experience_soms, train_grasp_som

DEFAULT_EXPERIENCE = {
    HARD_GRID.name: shipped("grasp", "experience_hard"),
    THESIS_GRID.name: shipped("grasp", "experience"),
}
"""Shipped experience (grasp dataset + SOMs) per grid, regenerated with ``handflow grasp-experience
--grid GRID --train-soms`` (docs/grasping.md)."""
GRID_CHOICES = (HARD_GRID.name, THESIS_GRID.name)


def _progress(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def _objects(text: str | None, grid: GraspGrid) -> list[str]:
    """``--objects``: a comma-separated subset of the grid's objects (``None``: all of them)."""
    if text is None:
        return list(grid.objects)
    objs = [o.strip() for o in text.split(",") if o.strip()]
    bad = [o for o in objs if o not in grid.objects]
    if bad or not objs:
        raise ValueError(
            f"--objects takes a comma-separated subset of {','.join(grid.objects)} (grid '{grid.name}'), got {text!r}"
        )
    return objs


def _trials(text: str, objects: list[str]) -> int | dict[str, int]:
    """``--trials``: one count for every object (``250``) or per object (``box=250,cylinder=900``)."""
    try:
        if "=" not in text:
            return int(text)
        per = {k.strip(): int(v) for k, v in (item.split("=") for item in text.split(",") if item.strip())}
    except ValueError:
        raise ValueError(
            f"--trials takes a count (250) or object=count pairs (box=250,cylinder=900), got {text!r}"
        ) from None
    missing = [o for o in objects if o not in per]
    unknown = [o for o in per if o not in objects]
    if missing or unknown:
        raise ValueError(
            f"--trials {text!r}: give a count for exactly the objects {','.join(objects)} "
            f"(missing {missing}, not generated {unknown})"
        )
    return per


def _pair(text: str, name: str) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"{name} takes 'start,end' (e.g. 0.95,0.05), got {text!r}") from None
    return a, b


# -- grasp-experience ---------------------------------------------------------------------------
def register_generate(parser: argparse.ArgumentParser) -> None:
    """Generate grasp experience in pybullet (tactile grasps that pass the disturbance test), optionally train SOMs."""
    parser.description = (
        "Generate grasp experience in pybullet (randomised tactile grasps kept when they pass "
        "the disturbance test) and optionally train the SOM grasp manifolds."
    )
    parser.add_argument(
        "--grid",
        default=HARD_GRID.name,
        choices=GRID_CHOICES,
        help="evaluation grid the experience is for: its objects, ranges and friction; its poses are excluded",
    )
    parser.add_argument("--objects", default=None, help="comma-separated subset of the grid's objects (default all)")
    parser.add_argument(
        "--trials",
        default="400",
        help="grasp trials per object: a count, or object=count pairs "
        "(e.g. box=250,cylinder=900,sphere=200) to balance the experience",
    )
    parser.add_argument("--local-trials", type=int, default=3, help="jittered retries around each stable grasp")
    parser.add_argument(
        "--fixed-pregrasp",
        action="store_true",
        help="grasp from the evaluation's fixed pre-grasp (only pose and λ vary) instead of random pre-grasps",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--out", default="grasp_experience", help="output folder, relative to the current directory (gets grasps.npz)"
    )
    parser.add_argument("--train-soms", action="store_true", help="also write som_<object>.npz and som_shared.npz")
    parser.add_argument("--size", type=int, default=25, help="lattice size of the object-specific SOMs")
    parser.add_argument("--shared-size", type=int, default=30, help="lattice size of the shared SOM")
    parser.add_argument("--epochs", type=int, default=300)
    parser.set_defaults(func=run_generate)


def run_generate(args) -> int:
    try:
        grid = GRIDS[args.grid]
        objects = _objects(args.objects, grid)
        trials = _trials(str(args.trials), objects)
        if min(trials.values() if isinstance(trials, dict) else [trials]) < 1 or args.local_trials < 0:
            raise ValueError("--trials must be ≥ 1 and --local-trials ≥ 0")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with threadpool_limits(1):
        ranges = FIXED_PREGRASP_RANGES if args.fixed_pregrasp else PREGRASP_RANGES
        data = generate_experience(
            objects,
            trials,
            seed=args.seed,
            local_trials=args.local_trials,
            progress=_progress,
            pregrasp_ranges=ranges,
            grid=grid,
        )
        data.save(out / "grasps.npz")
        _progress(f"wrote {len(data)} stable grasps to {out / 'grasps.npz'}: {data.metadata['counts']}")
        if args.train_soms:
            try:
                train_experience_soms(
                    data, out, objects, args.size, args.shared_size, args.epochs, args.seed, _progress
                )
            except ValueError as exc:
                print(f"error: {exc}", file=sys.stderr)
                return 1
    return 0


# -- grasp-som -------------------------------------------------------------------------------------
def register_train_som(parser: argparse.ArgumentParser) -> None:
    """Train (or resume training of) a SOM grasp manifold on a grasp dataset; plot it."""
    parser.description = "Train (or resume training of) a SOM grasp manifold on a grasp dataset; plot it."
    parser.add_argument("data", help="grasp dataset (.npz from grasp-experience)")
    parser.add_argument("--object", default="all", help="box | cylinder | sphere | all")
    parser.add_argument("--out", required=True, help="SOM file to write (.npz)")
    parser.add_argument("--resume", help="SOM file to continue training (thesis: 10 epochs, ε 0.1→0.05, σ 3→0.7)")
    parser.add_argument("--rows", type=int, default=25)
    parser.add_argument("--cols", type=int, default=25)
    parser.add_argument("--epochs", type=int, default=None, help="default 300 (10 with --resume)")
    parser.add_argument(
        "--lr", default=None, help="start,end learning rate (default 0.95,0.05; 0.1,0.05 with --resume)"
    )
    parser.add_argument(
        "--sigma", default=None, help="start,end neighbourhood width (default 6,0.7; 3,0.7 with --resume)"
    )
    parser.add_argument("--mode", default="online", choices=("online", "batch"))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--umatrix", help="write the inter-node distance map (PNG)")
    parser.add_argument("--nodes", help="write rendered node postures (PNG)")
    parser.add_argument("--extract", type=int, default=10, help="nodes per side in the --nodes picture")
    parser.set_defaults(func=run_train_som)


def run_train_som(args) -> int:
    try:
        data = GraspDataset.load(args.data)
        obj = None if args.object == "all" else args.object
        part = data.select(obj)
        if len(part) == 0:
            raise ValueError(f"{args.data} has no grasps of '{args.object}'")
        with threadpool_limits(1):
            if args.resume:
                som, meta = load_som(args.resume)
                lr = _pair(args.lr, "--lr") if args.lr else (0.1, 0.05)
                sigma = _pair(args.sigma, "--sigma") if args.sigma else (3.0, 0.7)
                som.partial_fit(part.postures, epochs=args.epochs or 10, lr=lr, sigma=sigma)
            else:
                params = {
                    "lr": _pair(args.lr, "--lr") if args.lr else (0.95, 0.05),
                    "sigma": _pair(args.sigma, "--sigma") if args.sigma else (6.0, 0.7),
                    "mode": args.mode,
                }
                som = train_grasp_som(data, obj, args.rows, args.cols, args.epochs or 300, args.seed, **params)
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    qe, te = som.quantization_error(part.postures), som.topographic_error(part.postures)
    save_som(
        som,
        args.out,
        {
            "names": list(data.names),
            "object": args.object,
            "n_postures": len(part),
            "quantization_error": qe,
            "topographic_error": te,
            "data": str(args.data),
        },
    )
    _progress(f"wrote {args.out}: QE {qe:.4f} rad, topographic error {te:.3f} on {len(part)} grasps")
    if args.umatrix:
        plot_u_matrix(som, args.umatrix, hits=som.hits(part.postures), title=f"SOM grasp manifold ({args.object})")
    if args.nodes:
        plot_node_postures(som, data.names, args.nodes, extract=args.extract)
    return 0


# -- evaluate grasping -----------------------------------------------------------------------------
def register_evaluate(parser: argparse.ArgumentParser) -> None:
    """Grasp every object over a grid of poses (object SOM, no experience, shared SOM): shares of stable grasps."""
    parser.description = (
        "Grasp every object over a grid of poses with the object-specific SOM, without "
        "experience and with one shared SOM; report the shares of stable grasps per object and "
        "overall, pooled over seeds, with paired McNemar tests against the tactile baseline."
    )
    parser.add_argument("--grid", default=HARD_GRID.name, choices=GRID_CHOICES, help="pose grid and conditions")
    parser.add_argument("--quick", action="store_true", help=f"the {QUICK_HARD_GRID.name} subset, one seed; same keys")
    parser.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    parser.add_argument(
        "--experience", default=None, help="folder with som_<object>.npz and som_shared.npz (default: shipped)"
    )
    parser.add_argument("--objects", default=None, help="comma-separated subset of the grid's objects (default all)")
    parser.add_argument("--seeds", type=int, default=None, help="evaluation seeds 0 … N−1 (default 5; 1 with --quick)")
    parser.add_argument(
        "--repeats",
        type=int,
        default=1,
        help="pool this many runs per seed with γ jittered by ±2 %% steps",
    )
    parser.add_argument("--plots", default=None, help="write grasp success maps (PNG) into this folder")
    parser.set_defaults(func=run_evaluate)


def run_evaluate(args) -> int:
    try:
        if args.quick and args.grid != HARD_GRID.name:
            raise ValueError(f"--quick evaluates the {HARD_GRID.name} grid's subset; drop --grid {args.grid}")
        grid = QUICK_HARD_GRID if args.quick else GRIDS[args.grid]
        objects = _objects(args.objects, grid)
        seeds = args.seeds if args.seeds is not None else (1 if args.quick else 5)
        if seeds < 1:
            raise ValueError(f"--seeds must be ≥ 1, got {seeds}")
        experience = args.experience or DEFAULT_EXPERIENCE[grid.experience_grid]
        with threadpool_limits(1):
            result = evaluate_grasping(
                experience, grid, objects, progress=_progress, repeats=args.repeats, seeds=range(seeds)
            )
    except (ValueError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    outcomes = result.pop("outcomes")
    if args.plots:
        for path in plot_success_maps(outcomes, grid, Path(args.plots)):
            _progress(f"wrote {path}")
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print_tables(result, objects)
    return 0


def print_tables(result: dict, objects) -> None:
    """Per-object and overall shares with the paired test, then the spread over seeds."""
    print(
        f"grid {result['grid']} (friction {result['lateral_friction']:g}), seeds {result['seeds']}, "
        f"γ factors {result['gamma_factors']}"
    )
    print(
        f"{'object':14s} {'experience':>11s} {'no_exp':>8s} {'shared':>8s} {'n':>5s}  experience vs none: won/lost (McNemar p)"
    )
    for key in [*objects, "overall"]:
        r = result[key]
        pair = r["paired"]["experience"]
        print(
            f"{key:14s} {r['experience']:11.1%} {r['no_experience']:8.1%} {r['shared_som']:8.1%} {r['n_valid']:5d}"
            f"  {pair['wins']}/{pair['losses']} (p = {pair['p_sign']:.2g})"
        )
    print(f"{'seed':14s} {'experience':>11s} {'no_exp':>8s} {'gain':>8s}  won/lost (McNemar p)")
    for seed, r in result["per_seed"].items():
        pair = r["paired"]["experience"]
        gain = r["experience"] - r["no_experience"]
        print(
            f"{seed!s:14s} {r['experience']:11.1%} {r['no_experience']:8.1%} {gain:+8.1%}"
            f"  {pair['wins']}/{pair['losses']} (p = {pair['p_sign']:.2g})"
        )
    g = result["spread"]["experience_gain"]
    print(f"gain over seeds: mean {g['mean']:+.1%}, sd {g['std']:.1%}, range {g['min']:+.1%} … {g['max']:+.1%}")
    print(f"grasps per minute: {result['grasps_per_minute']:.1f}")
