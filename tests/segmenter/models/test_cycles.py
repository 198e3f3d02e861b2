"""Period detection, cycle splitting and class models trained on multi-cycle segments."""

from __future__ import annotations

import numpy as np
import pytest

from handflow.plugins.segmenter.evaluation import UKRCLMMethod
from handflow.plugins.segmenter.models import detect_period, split_cycles


def _cycles(shape, n_cycles: int, rng, speed_jitter: float = 0.3, noise: float = 0.02) -> np.ndarray:
    """``n_cycles`` repetitions of a closed 2D curve, each at its own speed (20–30 frames per cycle)."""
    parts = []
    for _ in range(n_cycles):
        n = int(25 * (1 + rng.uniform(-speed_jitter, speed_jitter) * 0.7))
        parts.append(shape(np.linspace(0, 2 * np.pi, n, endpoint=False)))
    Y = np.vstack(parts)
    return Y + rng.normal(0, noise, Y.shape)


def circle(t):
    return np.c_[np.cos(t), np.sin(t)]


def figure_eight(t):
    return np.c_[np.sin(t), np.sin(2 * t)]


@pytest.mark.parametrize("k", [3, 6, 9])
def test_split_cycles_finds_the_cycle_count_at_varying_speed(k):
    rng = np.random.default_rng(k)
    Y = _cycles(circle, k, rng)
    assert detect_period(Y) == pytest.approx(len(Y) / k, rel=0.25)
    pieces = split_cycles(Y)
    # cuts at the phase minimum of every cycle: k − 1 whole cycles between them (the partial ends are left out)
    assert len(pieces) == k - 1
    assert all(15 <= len(p) <= 40 for p in pieces)


def test_a_motion_without_repetition_stays_one_sequence():
    t = np.linspace(0, 1, 80)
    Y = np.c_[t, t**2]
    assert detect_period(Y) is None
    assert len(split_cycles(Y)) == 1


def test_a_model_trained_on_multi_cycle_segments_labels_a_single_cycle():
    rng = np.random.default_rng(0)
    segments = {0: [_cycles(circle, 5, rng) for _ in range(2)], 1: [_cycles(figure_eight, 5, rng) for _ in range(2)]}
    method = UKRCLMMethod()
    fitted = method.fit(segments, {"delay": 4, "history": 10}, seed=0)
    one = circle(np.linspace(0, 2 * np.pi, 24, endpoint=False))
    labels = method.labels(fitted, method.prepare(fitted, one), reject=0.0)
    assert np.mean(labels == 0) >= 0.8
