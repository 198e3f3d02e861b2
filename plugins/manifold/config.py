"""The ``model:`` and ``training:`` sections of a training config, the estimator they describe, and training progress (docs/training.md).

Shared by ``handflow train`` and the training modes of other families (``handflow.train_modes``).
"""

from __future__ import annotations

import argparse
import sys
from typing import Literal, Optional, Union

from pydantic import Field

from handflow.framework.files.params import StrictModel

from .kernels import KernelName
from .model import StructuredUKR
from .validation import InvalidInputError


class LatentConfig(StrictModel):
    kernel: KernelName
    beta: float = Field(gt=0)
    time: bool = False


class ModelConfig(StrictModel):
    latent: list[LatentConfig] = Field(min_length=1)
    time_dim: Optional[int] = None
    lambda_cseq: float = Field(1.0, ge=0)
    lambda_pvar: float = Field(1.0, ge=0)
    loo_cv: bool = True
    sparse: Union[bool, Literal["auto", "float32"]] = "auto"


class TrainingConfig(StrictModel):
    optimizer: Literal["rprop", "lbfgs"] = "rprop"
    n_steps: int = Field(500, ge=0)
    init: Literal["isomap", "equidistant"] = "isomap"
    isomap_neighbors: list[int] = Field(default_factory=lambda: [5, 10, 15], min_length=1)
    projection_steps: int = Field(10, ge=0)
    random_state: Optional[int] = 0


def build_model(m: ModelConfig, t: TrainingConfig, n_steps=None) -> StructuredUKR:
    """The unfitted estimator a config's ``model:`` and ``training:`` sections describe."""
    return StructuredUKR(
        latent=[d.model_dump() for d in m.latent],
        time_dim=m.time_dim,
        lambda_cseq=m.lambda_cseq,
        lambda_pvar=m.lambda_pvar,
        loo_cv=m.loo_cv,
        sparse=m.sparse,
        optimizer=t.optimizer,
        n_steps=t.n_steps if n_steps is None else n_steps,
        init=t.init,
        isomap_neighbors=tuple(t.isomap_neighbors),
        projection_steps=t.projection_steps,
        random_state=t.random_state,
    )


class TrainingProgress:
    """Rich progress bar on a terminal, otherwise ~20 plain lines on stderr."""

    def __init__(self, total, quiet=False):
        self.total, self.quiet = total, quiet
        self.bar = None
        if not quiet and sys.stderr.isatty():
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

            self.bar = Progress(
                TextColumn("training"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("objective {task.fields[obj]:.6g}"),
                console=Console(stderr=True),
                transient=False,
            )
            self.task = self.bar.add_task("train", total=total, obj=float("nan"))

    def __enter__(self):
        if self.bar:
            self.bar.start()
        return self

    def __exit__(self, *exc):
        if self.bar:
            self.bar.stop()

    def __call__(self, step, value):
        if self.bar:
            self.bar.update(self.task, completed=step, obj=value)
        elif not self.quiet and (step % max(1, self.total // 20) == 0 or step == self.total):
            print(f"step {step}/{self.total}  objective {value:.6g}", file=sys.stderr, flush=True)


def check_train_args(args: argparse.Namespace) -> None:
    """The ``--steps`` / ``--out`` checks shared by every training mode."""
    if args.steps is not None and args.steps < 0:
        raise InvalidInputError(f"--steps must be >= 0, got {args.steps}")
    if not args.out.parent.is_dir():
        raise InvalidInputError(f"--out: directory {args.out.parent} does not exist")
