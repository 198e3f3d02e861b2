"""How far a frame lies from what the classes were trained on: feature novelty and motion
intensity (docs/segmentation.md, "Intensity term", "Feature novelty")."""

from ._feature_novelty import (
    ARRAYS,
    COMPONENTS,
    MAD_TO_STD,
    NEIGHBOURS,
    SCALE_FLOOR,
    FeatureNovelty,
    distance_weight,
)
from ._intensity import (
    FLOOR,
    MAX_WINDOW,
    QUANTILE,
    SHARPNESS,
    WINDOW,
    IntensityRanges,
    IntensityStream,
    log_intensity,
)

__all__ = [
    "ARRAYS",
    "COMPONENTS",
    "FLOOR",
    "FeatureNovelty",
    "IntensityRanges",
    "IntensityStream",
    "MAD_TO_STD",
    "MAX_WINDOW",
    "NEIGHBOURS",
    "QUANTILE",
    "SCALE_FLOOR",
    "SHARPNESS",
    "WINDOW",
    "distance_weight",
    "log_intensity",
]
