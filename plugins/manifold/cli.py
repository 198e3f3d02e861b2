"""``handflow train CONFIG.yaml --out MODEL.npz [--plot DIR]`` (docs/training.md).

Exit codes: 0 ok (also after Ctrl-C, which saves the best model so far), 2 bad input
(config, data, layout — the message names what to change), 1 runtime failure.
"""

from __future__ import annotations

import argparse
import sys
from importlib.metadata import entry_points
from pathlib import Path
from typing import Literal, Optional, Union

import yaml
from pydantic import Field, model_validator

from handflow.framework.files.params import StrictModel
from handflow.framework.files.yaml import YamlFileError, load_model

from .data import load_csv_dir, load_mcap, load_npz
from .kernels import KernelName
from .model import StructuredUKR
from .plots import plot_training
from .sparse import dense_advice
from .validation import InvalidInputError


class DataConfig(StrictModel):
    """Exactly one source: ``csv_dir``, ``npz`` or ``mcap`` (+ ``topic``)."""

    csv_dir: Optional[Path] = None
    time_column: Optional[str] = None
    columns: Optional[list[str]] = None
    npz: Optional[Path] = None
    mcap: Optional[Path] = None
    topic: Optional[str] = None
    field: str = "positions"
    time_ranges: Optional[list[tuple[float, float]]] = None

    @model_validator(mode="after")
    def _one_source(self):
        given = [k for k in ("csv_dir", "npz", "mcap") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of csv_dir, npz, mcap (got {given or 'none'})")
        if self.mcap is not None and not self.topic:
            raise ValueError("mcap needs a topic")
        for a, b in self.time_ranges or []:
            if b < a:
                raise ValueError(f"time range [{a}, {b}] ends before it starts")
        return self


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


class TrainConfig(StrictModel):
    data: DataConfig
    model: ModelConfig
    training: TrainingConfig = Field(default_factory=TrainingConfig)


def load_config(path) -> TrainConfig:
    """Parse and validate a YAML config; relative data paths are relative to the file."""
    path = Path(path)
    if not path.is_file():
        raise InvalidInputError(f"config file {path} not found")
    try:
        cfg = load_model(path, TrainConfig)
    except YamlFileError as exc:
        raise InvalidInputError(f"invalid config — change:\n{exc}") from None
    for key in ("csv_dir", "npz", "mcap"):
        value = getattr(cfg.data, key)
        if value is not None and not value.is_absolute():
            setattr(cfg.data, key, path.parent / value)
    return cfg


def load_data(cfg: DataConfig):
    """Sequences and their names for the configured source."""
    if cfg.csv_dir is not None:
        return load_csv_dir(cfg.csv_dir, cfg.time_column, cfg.columns)
    if cfg.npz is not None:
        return load_npz(cfg.npz)
    return load_mcap(cfg.mcap, cfg.topic, cfg.field, cfg.time_ranges)


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


class _Progress:
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


def register_train(parser: argparse.ArgumentParser) -> None:
    """Entry point of group ``handflow.commands``: add the arguments of ``train``."""
    parser.description = "Train a Structured UKR manifold from a YAML config."
    parser.add_argument("config", type=Path, help="YAML config (see docs/training.md)")
    parser.add_argument("--out", type=Path, required=True, help="model file to write (.npz)")
    parser.add_argument("--plot", type=Path, metavar="DIR", help="write PNG plots into DIR")
    parser.add_argument("--steps", type=int, help="override training.n_steps")
    parser.add_argument("--quiet", action="store_true", help="no progress output")
    parser.set_defaults(func=run_train)


def _fail(code, msg):
    print(f"handflow train: error: {msg}", file=sys.stderr)
    return code


def check_train_args(args: argparse.Namespace) -> None:
    """The ``--steps`` / ``--out`` checks shared by every training mode."""
    if args.steps is not None and args.steps < 0:
        raise InvalidInputError(f"--steps must be >= 0, got {args.steps}")
    if not args.out.parent.is_dir():
        raise InvalidInputError(f"--out: directory {args.out.parent} does not exist")


def train_mode_handler(config: Path):
    """The command a config's top-level ``mode:`` names, or None for a plain UKR config.

    Other families add training modes through the entry-point group ``handflow.train_modes``
    (docs/training.md), so this library knows none of them.
    """
    try:
        raw = yaml.safe_load(Path(config).read_text())
    except (OSError, yaml.YAMLError):
        return None  # load_config reports the problem with its location
    mode = raw.get("mode") if isinstance(raw, dict) else None
    if mode is None:
        return None
    modes = {ep.name: ep for ep in entry_points(group="handflow.train_modes")}
    if mode not in modes:
        raise InvalidInputError(
            f"{config}: unknown mode {mode!r}; installed training modes: {', '.join(sorted(modes)) or 'none'}"
        )
    return modes[mode].load()


def run_train(args: argparse.Namespace) -> int:
    """Run ``train``; returns the exit code."""
    try:
        handler = train_mode_handler(args.config)
    except InvalidInputError as exc:
        return _fail(2, exc)
    if handler is not None:  # e.g. `mode: construction | learning` (docs/manipulation.md)
        return handler(args)
    try:
        cfg = load_config(args.config)
        check_train_args(args)
        sequences, names = load_data(cfg.data)
        model = build_model(cfg.model, cfg.training, args.steps)
        advice = dense_advice(model, sum(map(len, sequences)))
        if advice and not args.quiet:
            print(f"handflow train: note: {advice}", file=sys.stderr)
        with _Progress(model.n_steps, args.quiet) as progress:
            model.fit(sequences, callback=progress)
    except InvalidInputError as exc:
        return _fail(2, exc)
    except KeyboardInterrupt:
        return _fail(1, "interrupted before training started; nothing saved")
    except Exception as exc:
        return _fail(1, f"{type(exc).__name__}: {exc}")
    if model.interrupted_:
        print(
            f"interrupted after {len(model.history_) - 1} steps; saving the best model so "
            f"far (objective {model.objective_:.6g})",
            file=sys.stderr,
        )
    provenance = {"config": str(args.config), "config_content": cfg.model_dump(mode="json"), "sequences": names}
    try:
        model.save(args.out, provenance=provenance)
        if args.plot is not None:
            plot_paths = plot_training(model, args.plot)
            if not args.quiet:
                print("plots: " + ", ".join(map(str, plot_paths)), file=sys.stderr)
    except OSError as exc:
        return _fail(1, f"cannot write output: {exc}")
    if not args.quiet:
        print(
            f"saved {args.out} ({len(model.Y_)} points, {len(names)} sequences, objective {model.objective_:.6g})",
            file=sys.stderr,
        )
    return 0
