"""Manipulation manifolds from demonstration recordings: the ``construction`` and ``learning``
modes of ``handflow train`` (docs/manipulation.md).

A config with a top-level ``mode: construction | learning`` is handled here::

    mode: construction                 # docs/manipulation.md (cap demonstrations only)
    data: {demo: ../../recordings/cap_demos.mcap}
    construction: {time_beta: 30, radius_beta: 4, n_steps: 100}

    mode: learning                     # §3 (cap) or the ball-swap manifold (§4)
    data: {demo: ../../recordings/cap_demos.mcap}
    model: …                           # as in a plain UKR training config
    training: …

The written model file is a :class:`~.manifold_file.ManipulationManifold` (observation names,
hand, latent names).  Learning on cap data also reports how well the learned radius coordinate
orders the sequences by true radius (:func:`radius_order`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Literal, Optional

import numpy as np
from pydantic import Field
from scipy.stats import spearmanr

from handflow.framework.files.params import StrictModel
from handflow.framework.files.yaml import YamlFileError, load_model
from handflow.plugins.manifold.config import (
    ModelConfig,
    TrainingConfig,
    TrainingProgress,
    build_model,
    check_train_args,
)
from handflow.plugins.manifold.construction import ManifoldConstruction
from handflow.plugins.manifold.model import StructuredUKR
from handflow.plugins.manifold.validation import InvalidInputError

from .demos import Demonstrations, load_demonstrations
from .manifold_file import ManipulationManifold

MODES = ("construction", "learning")


class DemoData(StrictModel):
    demo: Path = Field(description="MCAP recording of `handflow demo-record` (relative to the config)")
    max_sequences_per_radius: Optional[int] = Field(None, ge=1, description="use only the first n")


class ConstructionParams(StrictModel):
    time_beta: float = Field(30.0, gt=0)
    radius_beta: float = Field(4.0, gt=0)
    lambda_cseq: float = Field(1.0, ge=0)
    synchronisation: Literal["monotone", "pointwise"] = "monotone"
    n_steps: int = Field(100, ge=0)
    optimizer: Literal["rprop", "lbfgs"] = "rprop"
    random_state: Optional[int] = 0


class ConstructionConfig(StrictModel):
    mode: Literal["construction"]
    data: DemoData
    construction: ConstructionParams = Field(default_factory=ConstructionParams)


class LearningConfig(StrictModel):
    mode: Literal["learning"]
    data: DemoData
    model: ModelConfig
    training: TrainingConfig = Field(default_factory=TrainingConfig)


def load_config(path):
    path = Path(path)
    try:
        cfg = load_model(
            path, choose=lambda d: ConstructionConfig if d.get("mode") == "construction" else LearningConfig
        )
    except YamlFileError as exc:
        raise InvalidInputError(f"invalid config — change:\n{exc}") from None
    if not cfg.data.demo.is_absolute():
        cfg.data.demo = path.parent / cfg.data.demo
    return cfg


def _select(demos: Demonstrations, limit: Optional[int]) -> Demonstrations:
    if limit is None or demos.radii_cm is None:
        return demos
    keep = [i for i, r in enumerate(demos.radii_cm) if np.sum(demos.radii_cm[:i] == r) < limit]
    return Demonstrations([demos.sequences[i] for i in keep], demos.names, demos.hand, demos.task, demos.radii_cm[keep])


def construct(demos: Demonstrations, params: ConstructionParams, callback=None):
    """The constructed (time, radius_cm) manifold of cap demonstrations."""
    if demos.radii_cm is None:
        raise InvalidInputError("construction needs radius-labelled cap demonstrations (`handflow demo-record cap`)")
    builder = ManifoldConstruction(**params.model_dump()).fit(demos.sequences, demos.radii_cm, callback=callback)
    manifold = ManipulationManifold(builder.model_, demos.names, demos.hand, ["time", "radius_cm"], "constructed")
    return manifold, {"sequence_radius_cm": builder.sequence_radius_.tolist()}


def learn(demos: Demonstrations, model_cfg: ModelConfig, train_cfg: TrainingConfig, n_steps=None, callback=None):
    """Structured UKR on the demonstrations (the radius is not given to the learner)."""
    model = build_model(model_cfg, train_cfg, n_steps)
    model.fit(demos.sequences, callback=callback)
    q = model.latents_.shape[1]
    time_dim = model.time_dim_
    latent_names = ["time" if l == time_dim else f"param{l}" for l in range(q)]
    kind = "ball_swap" if demos.task == "balls" else "learned"
    info = {}
    if demos.radii_cm is not None and q == 2:
        info = radius_order(model, demos.radii_cm)
        latent_names = ["time" if l == time_dim else "radius_latent" for l in range(q)]
    return ManipulationManifold(model, demos.names, demos.hand, latent_names, kind), info


def radius_order(model: StructuredUKR, radii_cm) -> dict:
    """How the learned non-time coordinate orders and separates the sequences by true radius.

    ``spearman``: ρ between per-sequence mean latent radius and true radius (sign = direction of
    the axis; |ρ| = 1 is a perfect order).  ``separation`` (documented choice): Fisher ratio of
    the latent radius coordinate — variance of the per-radius means over the mean within-radius
    variance of the points (large = well separated).
    """
    r_dim = 1 - int(model.time_dim_)
    ids = np.unique(model.sequence_ids_)
    coord = model.latents_[:, r_dim]
    means = np.array([coord[model.sequence_ids_ == s].mean() for s in ids])
    radii = np.asarray(radii_cm, dtype=float)
    rho = float(spearmanr(means, radii).statistic)
    point_r = radii[np.searchsorted(ids, model.sequence_ids_)]
    groups = [coord[point_r == r] for r in np.unique(radii)]
    within = np.mean([g.var() for g in groups])
    between = np.var([g.mean() for g in groups])
    return {"spearman": rho, "separation": float(between / max(within, 1e-300)), "sequence_means": means.tolist()}


def train_manifold(cfg, n_steps=None, callback=None):
    """Build the manifold of a validated config; returns ``(manifold, info)``."""
    demos = _select(load_demonstrations(cfg.data.demo), cfg.data.max_sequences_per_radius)
    if cfg.mode == "construction":
        params = cfg.construction if n_steps is None else cfg.construction.model_copy(update={"n_steps": n_steps})
        return construct(demos, params, callback)
    return learn(demos, cfg.model, cfg.training, n_steps, callback)


def run_manipulation_training(args: argparse.Namespace) -> int:
    """``handflow train CONFIG --out FILE`` for the modes of :data:`MODES`."""
    try:
        cfg = load_config(args.config)
        check_train_args(args)
        steps = (
            args.steps
            if args.steps is not None
            else (cfg.construction.n_steps if cfg.mode == "construction" else cfg.training.n_steps)
        )
        with TrainingProgress(steps, args.quiet) as progress:
            cb = progress if cfg.mode == "learning" else (lambda r, n, step, value: progress(step, value))
            manifold, info = train_manifold(cfg, args.steps, cb)
        manifold.save(
            args.out,
            provenance={
                "config": str(args.config),
                "mode": cfg.mode,
                "config_content": cfg.model_dump(mode="json"),
                "demo": str(cfg.data.demo),
                **info,
            },
        )
    except InvalidInputError as exc:
        print(f"handflow train: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"handflow train: error: cannot write output: {exc}", file=sys.stderr)
        return 1
    if not args.quiet:
        extra = "".join(f", {k} {info[k]:.3f}" for k in ("spearman", "separation") if k in info)
        print(f"saved {args.out} ({cfg.mode}, {len(manifold.model.Y_)} points{extra})", file=sys.stderr)
    return 0
