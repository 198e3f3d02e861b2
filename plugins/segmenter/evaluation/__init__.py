"""Evaluation protocols: open-set metrics, the method registry, the trajectory protocol and the
recordings protocol (docs/segmentation.md)."""

import warnings

from ._calibration import (
    CALIBRATIONS,
    FALLBACK_MARGIN,
    INNER_FOLDS,
    MIN_TRAINED_CLASSES,
    PSEUDO_UNKNOWNS,
    REJECT_ALL_OBJECTIVE,
    Choice,
)
from ._chosen import ChosenParameters
from ._fold_result import FoldResult
from ._folds import default_jobs
from ._methods import (
    MAX_FIT_RATIOS,
    MIN_PROGRESS,
    MIN_SPANS,
    REGISTRY,
    TRAJECTORY_METHODS,
    DTWMethod,
    Fitted,
    HMMMethod,
    Method,
    MiniRocketMethod,
    NoveltyCLMMethod,
    ScoreCLMMethod,
    ScoreMethod,
    ThresholdOnTrajectories,
    UKRCLMMethod,
    UKRCLMOnlineMethod,
    UKRMethod,
    UKROnlyMethod,
    methods_to_run,
    missing_extras,
)
from ._metrics import (
    calibrate,
    frame_metrics,
    score_thresholds,
    segment_counts,
    segment_f1,
    threshold_labels,
    tradeoff_curve,
)
from ._recordings import (
    DEFAULT_METHODS,
    NORMALISATIONS,
    RecordingsEvaluator,
    calibrate_background,
    calibrate_null_score,
)
from ._report import choice_summary, half_window
from ._trajectories import Evaluator
from ._trajectory_cases import (
    EXPERIMENTS,
    METHODS,
    REJECTION_EXPERIMENTS,
    SEGMENT_RULES,
    SELECTION_EXPERIMENTS,
    SELECTIONS,
    STRONG_BACKGROUND,
    Case,
    TrajectoryProtocol,
    build_cases,
    heading_choices,
    summarise,
)

__all__ = [
    "ChosenParameters",
    "REGISTRY",
    "TRAJECTORY_METHODS",
    "Method",
    "ThresholdOnTrajectories",
    "UKRCLMOnlineMethod",
    "CALIBRATIONS",
    "Case",
    "Choice",
    "DEFAULT_METHODS",
    "DTWMethod",
    "EXPERIMENTS",
    "Evaluator",
    "FALLBACK_MARGIN",
    "Fitted",
    "FoldResult",
    "HMMMethod",
    "INNER_FOLDS",
    "MAX_FIT_RATIOS",
    "METHODS",
    "MIN_PROGRESS",
    "MIN_SPANS",
    "MIN_TRAINED_CLASSES",
    "MiniRocketMethod",
    "NORMALISATIONS",
    "NoveltyCLMMethod",
    "PSEUDO_UNKNOWNS",
    "TrajectoryProtocol",
    "REJECTION_EXPERIMENTS",
    "REJECT_ALL_OBJECTIVE",
    "SEGMENT_RULES",
    "SELECTIONS",
    "SELECTION_EXPERIMENTS",
    "STRONG_BACKGROUND",
    "ScoreCLMMethod",
    "ScoreMethod",
    "RecordingsEvaluator",
    "UKRCLMMethod",
    "UKRMethod",
    "UKROnlyMethod",
    "build_cases",
    "heading_choices",
    "calibrate",
    "calibrate_background",
    "calibrate_null_score",
    "choice_summary",
    "default_jobs",
    "frame_metrics",
    "half_window",
    "methods_to_run",
    "missing_extras",
    "score_thresholds",
    "segment_counts",
    "segment_f1",
    "summarise",
    "threshold_labels",
    "tradeoff_curve",
]


def __getattr__(name: str):
    """``Protocol``: the deprecated name of :class:`TrajectoryProtocol` (it shadowed ``typing.Protocol``)."""
    if name == "Protocol":
        warnings.warn(
            "evaluation.Protocol is deprecated and goes in the next release: use TrajectoryProtocol",
            DeprecationWarning,
            stacklevel=2,
        )
        return TrajectoryProtocol
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
