"""The module paths of the flat layout before the sub-packages still import for one release, with a
DeprecationWarning naming the new path (plugins/segmenter/_moved.py, docs/architecture.md)."""

import importlib
import sys
import warnings

import pytest

from handflow.plugins.segmenter._moved import MOVED

PACKAGE = "handflow.plugins.segmenter"
# Every module of the flat layout and the public names it defined (from the tree before the move).
OLD_NAMES = {
    "baselines": ("PerClassHMM", "REJECTED", "SlidingDTW1NN", "decide"),
    "candidates": (
        "CandidateModel",
        "CandidateSet",
        "INDEX_FILE",
        "ModelsMissingError",
        "ObservationStream",
        "Projection",
        "TRAIN_HINT",
        "UKRCandidate",
        "load_candidates",
        "model_files",
        "stroke_seam",
        "training_direction",
    ),
    "cli": (
        "HEADINGS_ON_RECORDINGS",
        "format_table",
        "heading_channels",
        "register_evaluate",
        "register_train_classes",
        "run_evaluate",
        "run_train_classes",
        "write_plots",
    ),
    "clm": (
        "CLMResult",
        "CLMRun",
        "CompetitiveLayerModel",
        "LANCZOS_MIN_N",
        "clm_energy",
        "gershgorin_bound",
        "largest_eigenvalue",
    ),
    "clm_segmenter": ("CLMSegmenter", "ETA", "ETA_HEADED", "RECONSTRUCTIONS", "REJECTED"),
    "compatibility": (
        "ORDER_PATHS",
        "ORDER_RATINGS",
        "OrderRating",
        "PAIR_ERRORS",
        "PairError",
        "SPIKE_LENGTH",
        "SPIKE_STEP",
        "background_band",
        "bridged_latent",
        "candidate_band",
        "evidence_band",
        "evidence_temperature",
        "history_compatibility",
        "history_weights",
        "local_compatibility",
        "novelty_weight",
        "order_compatibility",
        "order_rating",
        "order_rating_cos",
        "order_rating_sign",
        "overall_compatibility",
        "pair_error",
        "pair_error_endpoints",
        "pair_error_max",
        "pair_error_mean",
        "reconstruction_compatibility",
        "reject_poor_fit",
        "reject_segments",
        "reject_small_progress",
        "score_evidence",
        "thesis_background_strength",
        "unwrapped_latent",
        "wrapped_step",
    ),
    "continuous": (
        "LABEL_COLUMN",
        "Recording",
        "RecordingSet",
        "UNLABELLED",
        "basicmotions_continuous",
        "is_continuous",
        "load_recordings",
        "segments",
    ),
    "cycles": ("MIN_CORRELATION", "SPAN", "detect_period", "phase_direction", "split_cycles"),
    "datasets": (
        "DatasetError",
        "LabelledDataset",
        "NPZ_HINT",
        "SPLITS",
        "TIME_COLUMNS",
        "Trajectory",
        "load_dataset",
        "split_counts",
    ),
    "delay": ("DelayEmbedding", "DelayStream"),
    "derived": ("DERIVED", "Derived", "DerivedStream", "FrameSteps", "derive"),
    "evaluation": (
        "Case",
        "EXPERIMENTS",
        "Evaluator",
        "MAX_FIT_RATIOS",
        "METHODS",
        "MIN_PROGRESS",
        "MIN_SPANS",
        "Protocol",
        "REJECTION_EXPERIMENTS",
        "SEGMENT_RULES",
        "SELECTIONS",
        "SELECTION_EXPERIMENTS",
        "STRONG_BACKGROUND",
        "build_cases",
        "summarise",
    ),
    "fast_projection": ("BatchedPeriodicProjector",),
    "feature_novelty": (
        "ARRAYS",
        "COMPONENTS",
        "FeatureNovelty",
        "MAD_TO_STD",
        "NEIGHBOURS",
        "SCALE_FLOOR",
        "distance_weight",
    ),
    "frame_methods": (
        "DTWMethod",
        "Fitted",
        "HMMMethod",
        "METHODS",
        "MiniRocketMethod",
        "NoveltyCLMMethod",
        "ScoreCLMMethod",
        "ScoreMethod",
        "UKRCLMMethod",
        "UKRMethod",
        "UKROnlyMethod",
    ),
    "headings": ("HeadingStream", "Headings", "SOFTNESS_OF_MEDIAN_STEP"),
    "intensity": (
        "FLOOR",
        "IntensityRanges",
        "IntensityStream",
        "MAX_WINDOW",
        "QUANTILE",
        "SHARPNESS",
        "WINDOW",
        "log_intensity",
    ),
    "nodes": ("OnlineCLMNode", "RecognizerParams", "UKROnlyNode", "UNKNOWN", "running_normaliser"),
    "online": ("OnlineCLMSegmenter", "OnlineUpdate", "SegmentChange", "SegmentTracker"),
    "online_scores": ("OnlineScoreCLMSegmenter", "batch_labels", "known_weights"),
    "openset": (
        "REJECTED",
        "calibrate",
        "frame_metrics",
        "runs",
        "score_thresholds",
        "segment_counts",
        "segment_f1",
        "threshold_labels",
        "tradeoff_curve",
    ),
    "plots": (
        "plot_compatibilities",
        "plot_confusion",
        "plot_label_ribbons",
        "plot_labelled_trajectory",
        "plot_summary",
        "plot_tradeoff",
    ),
    "running_scaling": ("RunningStandardizer", "RunningStream"),
    "scaling": ("ChannelScaling", "MIN_SCALE"),
    "scorers": (
        "DTWScorer",
        "FORMAT",
        "FORMAT_VERSION",
        "MiniRocketScorer",
        "SCORERS",
        "ScorerFileError",
        "WINDOWS_PER_SEGMENT",
        "WindowScorer",
        "causal_windows",
        "load_scorer",
    ),
    "stream_cli": (
        "format_stream_table",
        "known_segments",
        "register_fit_scorer",
        "register_make_continuous",
        "run_fit_scorer",
        "run_make_continuous",
        "run_stream_evaluation",
        "run_train_recording_models",
        "write_stream_plots",
    ),
    "stream_evaluation": (
        "CALIBRATIONS",
        "Choice",
        "DEFAULT_METHODS",
        "FALLBACK_MARGIN",
        "FoldResult",
        "INNER_FOLDS",
        "MIN_TRAINED_CLASSES",
        "NORMALISATIONS",
        "PSEUDO_UNKNOWNS",
        "REJECT_ALL_OBJECTIVE",
        "StreamEvaluator",
    ),
    "synthetic": ("LetterGenerator",),
    "training": (
        "CYCLES",
        "INITS",
        "KERNELS",
        "MAX_POINTS_PER_CLASS",
        "MIN_PERIOD",
        "SCALINGS",
        "auto_beta",
        "candidate_set",
        "class_pieces",
        "fit_class_models",
        "fit_recording_models",
        "periodic_class_model",
        "save_class_models",
        "thin_pieces",
        "train_class_models",
    ),
    "ukr_only": ("REJECTED", "UKROnlyRecognizer"),
}


@pytest.mark.parametrize("old", sorted(set(OLD_NAMES) & set(MOVED)))
def test_a_moved_module_path_warns_and_keeps_its_names(old):
    sys.modules.pop(f"{PACKAGE}.{old}", None)
    new = f"{PACKAGE}.{MOVED[old].partition('.')[0]}"
    with pytest.warns(DeprecationWarning, match=f"{PACKAGE}.{old} is deprecated.*import from {new}$"):
        module = importlib.import_module(f"{PACKAGE}.{old}")
    new_home = importlib.import_module(f"{PACKAGE}.{MOVED[old]}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # renamed names, tested below
        missing = [name for name in OLD_NAMES[old] if not hasattr(module, name)]
        assert not missing
        assert all(getattr(module, n) is getattr(new_home, n) for n in OLD_NAMES[old] if hasattr(new_home, n))


@pytest.mark.parametrize("old", sorted(set(OLD_NAMES) - set(MOVED)))
def test_a_module_path_that_is_now_a_package_keeps_its_names(old):
    module = importlib.import_module(f"{PACKAGE}.{old}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # evaluation.Protocol, tested below
        missing = [name for name in OLD_NAMES[old] if not hasattr(module, name)]
    assert not missing


def test_a_moved_module_is_an_attribute_of_the_package_with_a_warning():
    sys.modules.pop(f"{PACKAGE}.clm_segmenter", None)
    vars(importlib.import_module(PACKAGE)).pop("clm_segmenter", None)  # set by an earlier import
    with pytest.warns(DeprecationWarning, match="import from handflow.plugins.segmenter.clm$"):
        from handflow.plugins.segmenter import clm_segmenter
    assert clm_segmenter.CLMSegmenter is importlib.import_module(f"{PACKAGE}.clm").CLMSegmenter


def test_protocol_is_a_deprecated_name_of_trajectory_protocol():
    from handflow.plugins.segmenter.evaluation import TrajectoryProtocol

    with pytest.warns(DeprecationWarning, match="use TrajectoryProtocol"):
        from handflow.plugins.segmenter.evaluation import Protocol
    assert Protocol is TrajectoryProtocol


@pytest.mark.parametrize(
    "old, name, new",
    [
        ("stream_evaluation", "StreamEvaluator", "RecordingsEvaluator"),
        ("stream_cli", "run_stream_evaluation", "run_recordings_evaluation"),
        ("stream_cli", "write_stream_plots", "write_recordings_plots"),
    ],
)
def test_the_renamed_recordings_names_warn_with_their_new_name(old, name, new):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        module = importlib.import_module(f"{PACKAGE}.{old}")
    with pytest.warns(DeprecationWarning, match=f"{name} is deprecated.*use {new}$"):
        renamed = getattr(module, name)
    assert renamed is getattr(module, new)
