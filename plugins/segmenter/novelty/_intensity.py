"""Motion intensity ranges of the class models: how vigorously each channel moves (docs/segmentation.md,
"Intensity term").

A class manifold judges a frame's *shape*; a motion much gentler or more vigorous than anything a
class was trained on may still lie close to it (a standing subject's nearly constant windows lie
near every manifold that passes through a quiet stretch).  The intensity of a frame is the log of
each channel's standard deviation over the causal window of the last :data:`WINDOW` frames
(:class:`..features.DelayEmbedding`: the first frame stands in for the missing past, so a stream
equals the whole recording).  It does not depend on a channel's unit or scale.  Each class keeps
the range of its training frames' intensities per channel (quantiles :data:`QUANTILE` and
1 − :data:`QUANTILE`).  A frame's *excess* for a class is the largest log-factor by which one of its
channels lies outside that class's range, and its weight for the class ``exp(−SHARPNESS · excess)``,
1 inside the range (documented choices); the novelty term scales each class's evidence by it
(:func:`..compatibility.novelty_weight`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..features import DelayEmbedding

WINDOW = 16  # frames of the causal window an intensity is measured over
QUANTILE = 0.01  # a class's range spans these quantiles of its training frames' intensities
SHARPNESS = 2.0  # weight exp(−2·excess): a channel 2× outside every range keeps a quarter
FLOOR = 1e-3  # standard deviations below this share of the pooled one count as this much
MAX_WINDOW = 10_000  # a model file asking for a longer window is refused (tampered or foreign)


def log_intensity(Y: np.ndarray, floor: np.ndarray, window: int = WINDOW) -> np.ndarray:
    """(T, d) observations → (T, d) log standard deviations over each frame's causal window; NaN
    for the first ``window − 1`` frames, whose window is not complete yet."""
    Y = np.asarray(Y, dtype=float)
    windows = DelayEmbedding(int(window)).transform(Y).reshape(len(Y), int(window), Y.shape[1])
    intensity = _log_std(windows, floor, axis=1)
    intensity[: int(window) - 1] = np.nan
    return intensity


def _log_std(values: np.ndarray, floor: np.ndarray, axis: int) -> np.ndarray:
    return np.log(np.maximum(values.std(axis=axis), floor))


def _segment_intensity(segment: np.ndarray, floor: np.ndarray) -> np.ndarray:
    if len(segment) >= WINDOW:
        return log_intensity(segment, floor)[WINDOW - 1 :]
    return _log_std(segment, floor, axis=0)[None]


@dataclass
class IntensityRanges:
    """Per class (rows, in candidate order) the low and high intensity per channel (M, d), given or
    learned by :meth:`fit` (the streaming contract), with the channels' ``floor`` (d,)."""

    low: np.ndarray | None = None
    high: np.ndarray | None = None
    floor: np.ndarray | None = None
    window: int = WINDOW

    def fit(self, by_class: dict[str, list[np.ndarray]], y=None) -> IntensityRanges:
        """Ranges of each class's training segments (complete windows only; a segment shorter
        than a window counts once, with its whole length as the window); returns the ranges."""
        frames = np.vstack([s for segs in by_class.values() for s in segs])
        floor = np.maximum(FLOOR * frames.std(axis=0), np.finfo(float).tiny)
        low, high = [], []
        for segs in by_class.values():
            values = np.vstack([_segment_intensity(s, floor) for s in segs])
            low.append(np.quantile(values, QUANTILE, axis=0))
            high.append(np.quantile(values, 1.0 - QUANTILE, axis=0))
        self.low, self.high, self.floor = np.array(low), np.array(high), floor
        return self

    def class_provenance(self, row: int) -> dict:
        """What one class model stores (its own range and the shared floor and window)."""
        return {
            "intensity_low": self.low[row].tolist(),
            "intensity_high": self.high[row].tolist(),
            "intensity_floor": self.floor.tolist(),
            "intensity_window": int(self.window),
        }

    @classmethod
    def from_provenances(cls, provenances: list[dict]) -> IntensityRanges | None:
        """The ranges of a set of class models, or None when some model has none (models trained
        before intensity ranges existed); refused when the models measured intensity differently."""
        if not all("intensity_low" in p for p in provenances):
            return None
        try:
            floors = {tuple(float(v) for v in p["intensity_floor"]) for p in provenances}
            windows = {int(p["intensity_window"]) for p in provenances}
            low = np.array([[float(v) for v in p["intensity_low"]] for p in provenances])
            high = np.array([[float(v) for v in p["intensity_high"]] for p in provenances])
        except (KeyError, TypeError, ValueError, OverflowError) as exc:  # OverflowError: int(inf)
            raise ValueError(f"a model's intensity range is malformed ({exc}); retrain the class models") from None
        if len(floors) > 1 or len(windows) > 1 or low.shape != high.shape or low.shape[1] != len(next(iter(floors))):
            raise ValueError("class models measured intensity differently; retrain them together")
        floor, window = np.array(floors.pop()), windows.pop()
        if not (1 <= window <= MAX_WINDOW and np.all(floor > 0) and np.isfinite(floor).all()):
            raise ValueError(
                f"a model's intensity window {window} or floor {floor} is invalid; retrain the class models"
            )
        return cls(low, high, floor, window)

    def weights(self, intensity: np.ndarray) -> np.ndarray:
        """Per frame and class (N, M): ``exp(−SHARPNESS · excess)`` of log intensities (N, d); 1
        for a frame whose window is not complete (NaN)."""
        I = np.asarray(intensity, dtype=float)[:, None, :]
        excess = np.maximum(0.0, np.maximum(self.low[None] - I, I - self.high[None])).max(axis=2)
        return np.exp(-SHARPNESS * np.nan_to_num(excess, nan=0.0))

    def stream(self) -> IntensityStream:
        return IntensityStream(self)


class IntensityStream:
    """Log intensities one observation at a time, equal to :func:`log_intensity` of the whole stream."""

    def __init__(self, ranges: IntensityRanges) -> None:
        self.ranges = ranges
        self._delay = DelayEmbedding(int(ranges.window)).stream()
        self._seen = 0

    def push(self, y: np.ndarray) -> np.ndarray:
        """(1, d) log intensity of the newest observation y (d,); NaN until the window is complete."""
        y = np.asarray(y, dtype=float).reshape(-1)
        window = self._delay.push(y).reshape(int(self.ranges.window), y.size)
        self._seen += 1
        if self._seen < self.ranges.window:
            return np.full((1, y.size), np.nan)
        return _log_std(window, self.ranges.floor, axis=0)[None]
