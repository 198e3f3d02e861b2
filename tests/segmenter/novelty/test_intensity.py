"""Motion intensity ranges of the class models (plugins/segmenter/novelty/_intensity.py)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from handflow.plugins.manifold import StructuredUKR
from handflow.plugins.segmenter.models import fit_recording_models, load_candidates, save_class_models
from handflow.plugins.segmenter.novelty import WINDOW, IntensityRanges, log_intensity


def _sine(amplitude: float, n: int = 200, period: float = 25.0, seed: int = 0) -> np.ndarray:
    t = np.arange(n)
    noise = np.random.default_rng(seed).normal(0, 0.01, (n, 2))
    return amplitude * np.c_[np.sin(2 * np.pi * t / period), np.cos(2 * np.pi * t / period)] + noise


@settings(max_examples=40, deadline=None)
@given(
    Y=arrays(float, st.tuples(st.integers(1, 40), st.integers(1, 3)), elements=st.floats(-1e3, 1e3)),
    window=st.integers(1, 20),
)
def test_a_stream_measures_intensity_as_the_whole_recording(Y, window):
    ranges = IntensityRanges(np.zeros((1, Y.shape[1])), np.ones((1, Y.shape[1])), np.full(Y.shape[1], 1e-6), window)
    stream = ranges.stream()
    streamed = np.vstack([stream.push(y) for y in Y])
    assert np.allclose(streamed, log_intensity(Y, ranges.floor, window), equal_nan=True)
    assert np.isnan(streamed[: window - 1]).all() and np.isfinite(streamed[window - 1 :]).all()


def test_intensity_is_measured_in_log_units_whatever_a_channels_scale():
    Y = _sine(1.0)
    floor = np.full(2, 1e-9)
    assert np.allclose(log_intensity(7.0 * Y, floor), np.log(7.0) + log_intensity(Y, floor), equal_nan=True)


def test_gentler_or_more_vigorous_motion_falls_outside_the_range_of_its_class():
    ranges = IntensityRanges().fit({"circle": [_sine(1.0, seed=1), _sine(1.2, seed=2)]})
    weights = {a: ranges.weights(log_intensity(_sine(a, seed=3), ranges.floor))[:, 0] for a in (0.2, 1.1, 5.0)}
    assert np.all(weights[1.1] == 1.0)  # within the trained amplitudes
    settled = slice(WINDOW - 1, None)
    assert np.all(weights[0.2][settled] < 0.1) and np.all(weights[5.0][settled] < 0.1)
    assert np.all(weights[0.2][: WINDOW - 1] == 1.0)  # no judgement before a window is complete


def test_class_models_keep_their_intensity_ranges_through_save_and_load(tmp_path):
    models = fit_recording_models(
        {"slow": [_sine(1.0, seed=1)], "big": [_sine(4.0, period=12, seed=2)]}, delay=4, n_steps=20
    )
    loaded = load_candidates(save_class_models(models, tmp_path / "models"))
    assert np.allclose(loaded.intensity.low, models.intensity.low)
    assert np.allclose(loaded.intensity.high, models.intensity.high)
    weights = loaded.intensity_weights(_sine(4.0, period=12, seed=5))[WINDOW:]
    assert np.mean(weights[:, 1] == 1.0) > 0.9 and np.all(weights[:, 0] < 0.1)  # big motion: only 'big' holds it
    assert np.allclose(loaded.without("slow").intensity.low, models.intensity.low[1:])

    path = tmp_path / "models" / "big.npz"
    model = StructuredUKR.load(path)
    model.provenance_ = {k: v for k, v in model.provenance_.items() if not k.startswith("intensity_")}
    model.save(path)
    older = load_candidates(tmp_path / "models")  # one model from before intensity ranges: no intensity term
    assert older.intensity is None and np.all(older.intensity_weights(_sine(9.0)) == 1.0)


@pytest.mark.parametrize(
    "change, needle",
    [
        ({"intensity_low": ["a", "b"]}, "malformed"),
        ({"intensity_window": 8}, "differently"),
        ({"intensity_high": [1.0]}, "malformed"),
        ({"intensity_floor": [1e-3]}, "differently"),
    ],
)
def test_inconsistent_intensity_ranges_are_refused(change, needle):
    good = IntensityRanges(np.zeros((2, 2)), np.ones((2, 2)), np.full(2, 1e-3))
    provenances = [good.class_provenance(0), {**good.class_provenance(1), **change}]
    with pytest.raises(ValueError, match=needle):
        IntensityRanges.from_provenances(provenances)


def test_the_novelty_weight_keeps_the_evidence_of_classes_whose_intensity_a_frame_has():
    from handflow.plugins.segmenter.compatibility import novelty_weight

    errors = np.array([[1.0, 3.0], [1.0, 3.0], [40.0, 50.0]])  # frames 0-1 fit class 0's manifold; frame 2 none
    intensity = np.array([[1.0, 1.0], [0.25, 1.0], [1.0, 1.0]])  # frame 1 moves unlike class 0's training
    w = novelty_weight(errors, own_errors=np.array([1.0, 1.0]), novelty=0.25, intensity=intensity)
    assert np.allclose(w[0], 1.0) and np.allclose(w[1], [0.25, 1.0]) and np.allclose(w[2], 0.1)


JSONISH = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=True) | st.text(max_size=4),
    lambda inner: st.lists(inner, max_size=4),
    max_leaves=12,
)


@settings(max_examples=200, deadline=None)
@given(key=st.sampled_from(["intensity_low", "intensity_high", "intensity_floor", "intensity_window"]), value=JSONISH)
@example(key="intensity_window", value=float("inf"))  # int(inf) raises OverflowError, not ValueError
def test_a_tampered_intensity_range_is_a_clear_error_or_a_usable_range(key, value):
    good = IntensityRanges(np.zeros((2, 2)), np.ones((2, 2)), np.full(2, 1e-3))
    provenances = [good.class_provenance(0), {**good.class_provenance(1), key: value}]
    try:
        ranges = IntensityRanges.from_provenances(provenances)
    except ValueError as exc:
        assert "retrain" in str(exc)
    else:
        assert ranges.weights(log_intensity(np.zeros((3, 2)), ranges.floor, ranges.window)).shape == (3, 2)
