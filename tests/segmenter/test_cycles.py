"""Period detection and cycle splitting (plugins/segmenter/cycles.py)."""

import numpy as np
import pytest

from handflow.plugins.segmenter.cycles import cycle_boundaries, estimate_period, split_cycles


def multi_cycle(k: int, period: int, seed: int = 0, drift: float = 0.3) -> np.ndarray:
    """k repetitions of a 3-channel loop whose speed drifts by ±drift and amplitude by ±20 %."""
    rng = np.random.default_rng(seed)
    t = np.arange(k * period)
    speed = 1.0 + drift * np.sin(2 * np.pi * t / t.size + 1.0)
    phase = np.cumsum(speed)
    phase = phase / phase[-1] * 2 * np.pi * k
    amp = 1.0 + 0.2 * np.sin(3.0 * t / t.size)
    Y = np.c_[np.sin(phase), 0.5 * np.sin(2 * phase), np.cos(phase)] * amp[:, None]
    return Y + 0.05 * rng.normal(size=Y.shape)


@pytest.mark.parametrize("k", [3, 5, 8])
@pytest.mark.parametrize("period", [20, 60])
def test_period_detection_counts_cycles_at_varying_speed(k, period):
    Y = multi_cycle(k, period, seed=k + period)
    p = estimate_period(Y)
    assert p is not None and 0.7 * period <= p <= 1.4 * period
    b = cycle_boundaries(Y, p)
    assert k - 1 <= len(b) <= k  # one boundary per repetition (one may fall on the segment's edge)
    cycles = split_cycles(Y)
    assert len(cycles) == len(b) - 1  # the partial cycles at both ends are dropped
    assert 0.8 * period <= np.mean([len(c) for c in cycles]) <= 1.25 * period


def test_open_stroke_is_not_split():
    t = np.linspace(0.0, 1.0, 120)
    stroke = np.c_[t, t**2, np.sin(2.0 * t)]
    assert estimate_period(stroke) is None
    (whole,) = split_cycles(stroke)
    assert whole.shape == stroke.shape


def test_bad_segment_is_refused():
    Y = multi_cycle(3, 20)
    Y[5, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        split_cycles(Y)


def loop(kind: str, k: int, period: int, seed: int) -> np.ndarray:
    """k cycles of a circle ("circle") or a figure eight ("eight") with drifting speed."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(k * period))
    phase = np.cumsum(1.0 + 0.25 * np.sin(2 * np.pi * t / t.size + seed))
    phase = phase / phase[-1] * 2 * np.pi * k
    if kind == "circle":
        Y = np.c_[np.cos(phase), np.sin(phase), 0.3 * np.sin(phase)]
    else:
        Y = np.c_[np.sin(phase), np.sin(2 * phase), 0.3 * np.cos(phase)]
    return Y + 0.03 * rng.normal(size=Y.shape)


def test_model_trained_on_multi_cycle_segments_labels_a_single_cycle():
    from handflow.plugins.segmenter import CLMSegmenter
    from handflow.plugins.segmenter.training import candidate_set, class_pieces, fit_class_models

    train = {kind: [loop(kind, k, 30 + 5 * k, seed=k) for k in (3, 4, 5)] for kind in ("circle", "eight")}
    pieces, periodic = class_pieces(train["circle"], "auto", max_points=1500)
    assert periodic and len(pieces) >= 6
    models = fit_class_models(train, n_steps=60, cycles="auto", random_state=0)
    assert not any(m.provenance_["open_stroke"] for m in models.values())
    cands = candidate_set(models)
    for label, kind in enumerate(("circle", "eight")):
        one_cycle = loop(kind, 1, 40, seed=7)
        labels = CLMSegmenter(cands, history=10, random_state=0).fit_predict(one_cycle)
        assert np.mean(labels == label) >= 0.85
