"""Online segmenters: the CLM and the score CLM run incrementally, one sample at a time
(docs/segmentation.md)."""

from ._scores import (
    OnlineScoreCLMSegmenter,
    batch_labels,
    known_weights,
)
from ._segmenters import (
    OnlineCLMSegmenter,
    OnlineUpdate,
    SegmentChange,
    SegmentTracker,
)

__all__ = [
    "OnlineCLMSegmenter",
    "OnlineScoreCLMSegmenter",
    "OnlineUpdate",
    "SegmentChange",
    "SegmentTracker",
    "batch_labels",
    "known_weights",
]
