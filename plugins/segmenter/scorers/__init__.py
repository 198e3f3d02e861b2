"""Window scorers and the baselines: sliding DTW 1-NN, per-class HMM and MiniRocket, with the
scorer files (docs/segmentation.md)."""

from ._baselines import (
    PerClassHMM,
    SlidingDTW1NN,
    decide,
)
from ._window import (
    FORMAT,
    FORMAT_VERSION,
    SCORERS,
    WINDOWS_PER_SEGMENT,
    DTWScorer,
    MiniRocketScorer,
    ScorerFileError,
    WindowScorer,
    causal_windows,
    load_scorer,
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
    "WINDOWS_PER_SEGMENT",
    "WindowScorer",
    "causal_windows",
    "decide",
    "load_scorer",
]
