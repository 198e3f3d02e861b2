"""``handflow evaluate manipulation [--quick] [--json]`` (docs/manipulation.md).

Runs the scenarios headless (:mod:`.evaluation`) on the project's own manifolds.  Missing
manifolds are built on first use and cached in ``--models`` (default ``configs/models``):
the demonstrations are recorded with the demo recorder if ``recordings/`` lacks them, then the
training configs ``configs/train/cap_construction.yaml``, ``cap_learning.yaml`` and
``ball_swap.yaml`` are run (again whenever a recording is newer than its cached manifold).
Exit codes: 0 ok, 2 bad input, 1 failure.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from handflow.framework.files.resources import shipped
from handflow.plugins.manifold.validation import InvalidInputError

from .evaluation import EvalPlan, evaluate
from .manifold_file import ManipulationManifold
from .training import load_config, train_manifold

TRAIN_CONFIGS = shipped("train")
CONFIGS_MODELS = shipped("models")
MODELS = {
    "constructed": ("cap_construction.yaml", "cap_constructed.npz"),
    "learned": ("cap_learning.yaml", "cap_learned.npz"),
    "balls": ("ball_swap.yaml", "ball_swap.npz"),
}
"""Manifold name → (training config, cached model file)."""


def _say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def _record_if_missing(demo: Path, say) -> None:
    if demo.is_file():
        return
    from handflow.plugins.demo.demonstrations import record_balls, record_cap

    say(f"recording demonstrations into {demo} …")
    demo.parent.mkdir(parents=True, exist_ok=True)
    (record_balls if "ball" in demo.name else record_cap)(demo, progress=say)


def ensure_manifold(name: str, models_dir: Path, say=_say) -> Path:
    """Path of the cached manifold ``name`` (see :data:`MODELS`), built on first use and rebuilt
    when its demonstration recording is newer than the cached file.  The manifolds shipped with the
    package are used as they are: nothing is ever written into the installed package."""
    config, filename = MODELS[name]
    path = models_dir / filename
    if models_dir == CONFIGS_MODELS:
        if not path.is_file():
            raise InvalidInputError(f"the shipped manifold {path} is missing; pass --models DIR to build one there")
        return path
    cfg = load_config(TRAIN_CONFIGS / config)
    demo = cfg.data.demo
    if path.is_file() and (not demo.is_file() or demo.stat().st_mtime <= path.stat().st_mtime):
        return path
    _record_if_missing(demo, say)
    say(f"training {name} manifold ({config}) — cached in {path}")
    steps = cfg.construction.n_steps if cfg.mode == "construction" else cfg.training.n_steps
    every = max(steps // 10, 1)

    def progress(*a):
        step, value = a[-2], a[-1]
        if len(a) == 4 and step == steps:  # construction: one line per sequence
            say(f"  radius {a[0]:g} cm, sequence {a[1] + 1}: objective {value:.5g}")
        elif len(a) == 2 and step % every == 0:
            say(f"  step {step}/{steps}  objective {value:.5g}")

    manifold, info = train_manifold(cfg, callback=progress)
    models_dir.mkdir(parents=True, exist_ok=True)
    manifold.save(
        path, provenance={"config": str(TRAIN_CONFIGS / config), "mode": cfg.mode, "demo": str(cfg.data.demo), **info}
    )
    return path


def register_evaluate(parser: argparse.ArgumentParser) -> None:
    """Evaluate the manipulation controllers headless: cap turning per radius, ball swapping; print a table."""
    parser.description = (
        "Evaluate the manipulation controllers headless: cap turning per radius, "
        "ball swapping open vs closed loop, control-loop latency."
    )
    parser.add_argument("--quick", action="store_true", help="reduced run (< 2 min), same keys")
    parser.add_argument("--json", action="store_true", help="print the results as JSON on stdout")
    parser.add_argument(
        "--models", type=Path, default=CONFIGS_MODELS, help="folder of cached manifolds (built on first use)"
    )
    parser.add_argument(
        "--plots", type=Path, default=None, metavar="DIR", help="write rate-over-time figures (PNG) into DIR"
    )
    parser.add_argument(
        "--seeds",
        type=int,
        default=None,
        help="number of seeds (disturbance timing, camera noise, start jitter); default 3, quick 1",
    )
    parser.add_argument("--jobs", type=int, default=1, help="worker processes for the ball-swap runs (default 1)")
    parser.set_defaults(func=run_evaluate)


def run_evaluate(args: argparse.Namespace) -> int:
    try:
        paths = {name: ensure_manifold(name, args.models) for name in MODELS}
        manifolds = {name: ManipulationManifold.load(p) for name, p in paths.items()}
    except InvalidInputError as exc:
        print(f"handflow evaluate manipulation: error: {exc}", file=sys.stderr)
        return 2
    plan = EvalPlan.quick() if args.quick else EvalPlan()
    if args.seeds is not None:
        if args.seeds < 1:
            print(f"handflow evaluate manipulation: error: --seeds must be >= 1, got {args.seeds}", file=sys.stderr)
            return 2
        plan.seeds = tuple(range(args.seeds))
    if args.jobs < 1:
        print(f"handflow evaluate manipulation: error: --jobs must be >= 1, got {args.jobs}", file=sys.stderr)
        return 2
    plan.jobs = args.jobs
    try:
        result = evaluate(
            manifolds["constructed"],
            manifolds["learned"],
            manifolds["balls"],
            plan,
            paths["balls"],
            progress=_say,
            plots=args.plots,
        )
    except Exception as exc:
        print(f"handflow evaluate manipulation: failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        _print_table(result)
    return 0


def _print_table(result: dict) -> None:
    print("cap turning (feedback-initialised): constructed manifold | learned manifold")
    print(f"  {'radius cm':>9}  {'deg/cycle':>9}  {'found cm':>8} | {'deg/cycle':>9}  {'found latent':>12}")
    for r, v in result["cap_turning"].items():
        w = result["cap_turning_learned"][r]
        print(
            f"  {r:>9}  {v['deg_per_cycle']:9.1f}  {v['found_radius']:8.2f} | "
            f"{w['deg_per_cycle']:9.1f}  {w['found_radius']:12.2f}"
        )
    print(
        f"disturbances (seeds {result['seeds']}; balls: swaps/min, cap: deg/min; median over seeds; "
        "recovered = back to >= 50 % of the calm rate within one hand cycle)"
    )
    print(f"  {'class':<13} {'controller':<14} {'calm':>7} {'rate':>7} {'x open':>6} {'recovered':>9} {'failed':>6}")
    for cls, row in result["disturbance_details"].items():
        for name, v in row.items():
            ratio = v["rate"] / row["open_loop"]["rate"] if row["open_loop"]["rate"] else float("nan")
            print(
                f"  {cls:<13} {name:<14} {v['calm_rate']:7.1f} {v['rate']:7.1f} {ratio:6.2f} "
                f"{v['recovered_share']:9.0%} {v['failures']:>3}/{v['disturbances']}"
            )
    print(f"learned radius: Spearman {result['radius_spearman']}, separation {result['radius_separation']}")
    print(f"control-loop latency ms (median, p99): {result['loop_latency_ms']}")
