"""Window scorers and the baselines: sliding DTW 1-NN, per-class HMM and MiniRocket, with the
scorer files (docs/segmentation.md)."""

from ._dtw import (
    MAX_REFERENCE_FRAMES,
    DTWScorer,
    SlidingDTW1NN,
    dtw_references,
)
from ._files import (
    SCORERS,
    load_scorer,
)
from ._hmm import (
    PerClassHMM,
)
from ._minirocket import (
    MAX_TRAINING_WINDOWS,
    WINDOWS_PER_SEGMENT,
    MiniRocketScorer,
)
from ._scores import (
    decide,
)
from ._window import (
    FORMAT,
    FORMAT_VERSION,
    ScorerFileError,
    WindowScorer,
    causal_windows,
)

__all__ = [
    "DTWScorer",
    "FORMAT",
    "FORMAT_VERSION",
    "MiniRocketScorer",
    "PerClassHMM",
    "SCORERS",
    "ScorerFileError",
    "SlidingDTW1NN",
    "MAX_REFERENCE_FRAMES",
    "MAX_TRAINING_WINDOWS",
    "WINDOWS_PER_SEGMENT",
    "WindowScorer",
    "causal_windows",
    "decide",
    "dtw_references",
    "load_scorer",
]
