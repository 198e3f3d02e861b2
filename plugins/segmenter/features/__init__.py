"""Causal feature transforms of a stream: channel scaling, running scaling, delay embedding,
derived features and headings (docs/segmentation.md)."""

from ._contract import CausalTransform, SampleStream
from ._delay import (
    DelayEmbedding,
    DelayStream,
)
from ._derived import (
    DERIVED,
    Derived,
    DerivedStream,
    FrameSteps,
    derive,
)
from ._headings import (
    SOFTNESS_OF_MEDIAN_STEP,
    Headings,
    HeadingStream,
)
from ._pipeline import FeaturePipeline, PipelineStream
from ._running_scaling import (
    RunningStandardizer,
    RunningStream,
)
from ._scaling import (
    MIN_SCALE,
    ChannelScaling,
    ScalingStream,
)

__all__ = [
    "FeaturePipeline",
    "PipelineStream",
    "CausalTransform",
    "SampleStream",
    "ScalingStream",
    "ChannelScaling",
    "DERIVED",
    "DelayEmbedding",
    "DelayStream",
    "Derived",
    "DerivedStream",
    "FrameSteps",
    "HeadingStream",
    "Headings",
    "MIN_SCALE",
    "RunningStandardizer",
    "RunningStream",
    "SOFTNESS_OF_MEDIAN_STEP",
    "derive",
]
