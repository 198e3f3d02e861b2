"""The segmenter's commands: train-classes, evaluate segmentation, basicmotions-continuous,
fit-scorer and dataset (docs/segmentation.md)."""

from ._commands import (
    HEADINGS_ON_RECORDINGS,
    format_table,
    heading_channels,
    register_evaluate,
    register_train_classes,
    run_evaluate,
    run_train_classes,
    write_plots,
)
from ._dataset import register_dataset, run_dataset
from ._recordings import (
    format_stream_table,
    known_segments,
    register_fit_scorer,
    register_make_continuous,
    run_fit_scorer,
    run_make_continuous,
    run_recordings_evaluation,
    run_train_recording_models,
    write_recordings_plots,
)

__all__ = [
    "register_dataset",
    "run_dataset",
    "HEADINGS_ON_RECORDINGS",
    "format_stream_table",
    "format_table",
    "heading_channels",
    "known_segments",
    "register_evaluate",
    "register_fit_scorer",
    "register_make_continuous",
    "register_train_classes",
    "run_evaluate",
    "run_fit_scorer",
    "run_make_continuous",
    "run_recordings_evaluation",
    "run_train_classes",
    "run_train_recording_models",
    "write_plots",
    "write_recordings_plots",
]
