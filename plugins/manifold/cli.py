"""``handflow train CONFIG.yaml --out MODEL.npz [--plot DIR]`` (docs/training.md).

Exit codes: 0 ok (also after Ctrl-C, which saves the best model so far), 2 bad input
(config, data, layout — the message names what to change), 1 runtime failure.
"""

from __future__ import annotations

import argparse
import sys
from importlib.metadata import entry_points
from pathlib import Path
from typing import Optional

import yaml
from pydantic import Field, model_validator

from handflow.framework.files.params import StrictModel
from handflow.framework.files.yaml import YamlFileError, load_model

from .config import ModelConfig, TrainingConfig, TrainingProgress, build_model, check_train_args
from .data import load_csv_dir, load_mcap, load_npz
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


def register_train(parser: argparse.ArgumentParser) -> None:
    """Train a structured UKR manifold from a YAML config."""
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
        with TrainingProgress(model.n_steps, args.quiet) as progress:
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
