"""The feature pipeline of a set of class models (docs/segmentation.md): derived features, then
heading channels, then the channel scaling, then the delay embedding — the input the models were
trained on, for a whole recording (:meth:`FeaturePipeline.transform`) or frame by frame
(:meth:`FeaturePipeline.stream`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._delay import DelayEmbedding
from ._derived import Derived
from ._headings import Headings
from ._scaling import ChannelScaling


@dataclass(frozen=True)
class FeaturePipeline:
    """``derived`` → ``headings`` → ``scaling`` (None: raw channels) → ``delay``."""

    derived: Derived = field(default_factory=Derived)
    headings: Headings = field(default_factory=Headings)
    scaling: ChannelScaling | None = None
    delay: DelayEmbedding = field(default_factory=DelayEmbedding)

    @classmethod
    def from_provenances(cls, provenances: list[dict], scaling: ChannelScaling | None = None) -> FeaturePipeline:
        """The pipeline a set of models records in their provenance (model files written before
        the pipeline was held explicitly); they must all record the same one."""
        delays = {DelayEmbedding.from_provenance(p) for p in provenances}
        if len(delays) > 1:
            raise ValueError(
                f"candidates were trained on different delay embeddings {sorted(map(str, delays))}; retrain them alike"
            )
        headings = {Headings.from_provenance(p) for p in provenances}
        if len(headings) > 1:
            raise ValueError(
                f"candidates were trained on different heading channels {sorted(map(str, headings))}; retrain them alike"
            )
        derived = {Derived.from_provenance(p) for p in provenances}
        if len(derived) > 1:
            raise ValueError(
                f"candidates were trained on different derived features {sorted(d.kind for d in derived)}; retrain them alike"
            )
        return cls(derived.pop(), headings.pop(), scaling, delays.pop())

    @property
    def stateful(self) -> bool:
        """True when a frame's model input depends on the frames before it."""
        return self.delay.window > 1 or self.headings.active or self.derived.active

    def fit(self, X=None, y=None) -> FeaturePipeline:
        """Nothing left to learn: the parts are fitted with the class models (the streaming contract)."""
        return self

    def scaled(self, Z: np.ndarray) -> np.ndarray:
        return Z if self.scaling is None else self.scaling.transform(Z)

    def transform(self, Y: np.ndarray) -> np.ndarray:
        """The model input (N, D) of frames Y (N, d), a contiguous stretch of a stream from its start."""
        return self.transform_both(Y)[0]

    def transform_both(self, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`transform` and the rows with their headings turned round (None without heading channels)."""
        Z = self.headings.transform(self.derived.transform(Y))
        rows = self.delay.transform(self.scaled(Z))
        if not self.headings.active:
            return rows, None
        return rows, self.delay.transform(self.scaled(self.headings.reversed(Z)))

    def stream(self) -> PipelineStream:
        """A frame-by-frame pipeline equal to :meth:`transform_both` of the whole stream."""
        return PipelineStream(self)


class PipelineStream:
    """Prepares one frame at a time (see :meth:`FeaturePipeline.stream`)."""

    def __init__(self, pipeline: FeaturePipeline) -> None:
        self.pipeline = pipeline
        self._derived = pipeline.derived.stream()
        self._headings = pipeline.headings.stream()
        self._delays = [pipeline.delay.stream() for _ in range(1 + pipeline.headings.active)]

    def push(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """The prepared row (1, D) of the newest frame y (d,), and the row with its heading turned
        round (None without heading channels)."""
        p = self.pipeline
        z = self._headings.push(self._derived.push(y))
        variants = [z, p.headings.reversed(z)] if p.headings.active else [z]
        rows = [d.push(p.scaled(v[None])[0])[None] for d, v in zip(self._delays, variants)]
        return rows[0], (rows[1] if len(rows) > 1 else None)
