"""Labelled trajectories, continuous recordings and synthetic letters (docs/segmentation.md)."""

from ._enrolment import (
    ADAPTATIONS,
    MIN_SPREAD,
    EnrolmentError,
    enrolment_recording,
    enrolment_split,
    session_aligned,
    session_alignment,
)
from ._labelled_mcap import (
    MIN_REPETITIONS,
    REST,
    Dataset,
    Stream,
    build_dataset,
    label_stream,
    read_stream,
    round_cuts,
)
from ._recordings import (
    LABEL_COLUMN,
    UNLABELLED,
    Recording,
    RecordingSet,
    basicmotions_continuous,
    is_continuous,
    load_recordings,
    segments,
)
from ._synthetic import (
    LetterGenerator,
)
from ._trajectories import (
    NPZ_HINT,
    SPLITS,
    TIME_COLUMNS,
    DatasetError,
    LabelledDataset,
    Trajectory,
    load_dataset,
    split_counts,
)

__all__ = [
    "MIN_REPETITIONS",
    "REST",
    "Dataset",
    "Stream",
    "build_dataset",
    "label_stream",
    "read_stream",
    "round_cuts",
    "ADAPTATIONS",
    "DatasetError",
    "EnrolmentError",
    "LABEL_COLUMN",
    "LabelledDataset",
    "LetterGenerator",
    "MIN_SPREAD",
    "NPZ_HINT",
    "Recording",
    "RecordingSet",
    "SPLITS",
    "TIME_COLUMNS",
    "Trajectory",
    "UNLABELLED",
    "basicmotions_continuous",
    "enrolment_recording",
    "enrolment_split",
    "is_continuous",
    "load_dataset",
    "load_recordings",
    "segments",
    "session_aligned",
    "session_alignment",
    "split_counts",
]
