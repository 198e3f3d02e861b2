"""Feature novelty: how far windows' features lie from the training windows (plugins/segmenter/novelty/_feature_novelty.py)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from handflow.plugins.segmenter.novelty import NEIGHBOURS, FeatureNovelty, distance_weight


def _training(seed: int = 0, n_segments: int = 12, per_segment: int = 10, dims: int = 60):
    """Windows' features on a low-dimensional cloud: 3 latent factors spread into ``dims`` features."""
    rng = np.random.default_rng(seed)
    mixing = rng.normal(size=(3, dims))
    latent = rng.normal(size=(n_segments * per_segment, 3))
    F = latent @ mixing + 0.05 * rng.normal(size=(len(latent), dims))
    return F, np.repeat(np.arange(n_segments), per_segment), mixing


def test_new_windows_like_the_training_ones_score_low_and_others_high():
    F, segments, mixing = _training()
    model = FeatureNovelty.fit(F, segments)
    rng = np.random.default_rng(1)
    alike = rng.normal(size=(200, 3)) @ mixing + 0.05 * rng.normal(size=(200, 60))
    off_cloud = alike + rng.normal(0.0, 1.0, size=alike.shape)  # directions the training never varied in
    far = alike + 8.0 * mixing[0]  # along a trained direction, but far out
    z_alike, z_off, z_far = model.novelty(alike), model.novelty(off_cloud), model.novelty(far)
    assert abs(np.median(z_alike)) < 1.5
    assert np.median(z_off) > 5 and np.median(z_far) > 5
    assert np.mean(z_off > np.quantile(z_alike, 0.9)) > 0.9


def test_the_training_windows_own_distances_leave_their_segment_out():
    F, segments, _ = _training()
    copies = np.repeat(F[:1], NEIGHBOURS + 1, axis=0)  # one segment of identical windows: 0 apart
    model = FeatureNovelty.fit(np.vstack([F, copies]), np.r_[segments, np.full(len(copies), 99)])
    assert model.reference[0] > 0.1  # a segment's own windows do not make the typical distance 0


def test_fit_needs_two_segments():
    F, _, _ = _training()
    with pytest.raises(ValueError, match="at least 2 segments"):
        FeatureNovelty.fit(F, np.zeros(len(F)))


def test_arrays_round_trip_and_bad_arrays_are_refused():
    F, segments, _ = _training()
    model = FeatureNovelty.fit(F, segments)
    arrays_ = model.arrays("n_")
    again = FeatureNovelty.from_arrays(arrays_, "n_", F.shape[1])
    np.testing.assert_array_equal(again.novelty(F[:7]), model.novelty(F[:7]))
    for name, bad in [
        ("n_mean", arrays_["n_mean"][:-1]),
        ("n_scale", -arrays_["n_scale"]),
        ("n_basis", np.full_like(arrays_["n_basis"], np.nan)),
        ("n_bank", arrays_["n_bank"][:, :-1]),
        ("n_reference", np.array([1.0, 0.0])),
    ]:
        with pytest.raises(ValueError):
            FeatureNovelty.from_arrays({**arrays_, name: bad}, "n_", F.shape[1])
    with pytest.raises(ValueError, match="shape"):
        FeatureNovelty.from_arrays(arrays_, "n_", F.shape[1] + 1)


@settings(max_examples=60, deadline=None)
@given(
    z=arrays(float, st.integers(1, 30), elements=st.floats(-50, 50)),
    limit=st.floats(-5, 10),
)
def test_distance_weight_is_one_up_to_the_limit_then_falls(z, limit):
    w = distance_weight(z, limit)
    assert np.all((w > 0) & (w <= 1))
    assert np.all(w[z <= limit] == 1.0)
    order = np.argsort(z)
    assert np.all(np.diff(w[order]) <= 1e-12)  # never larger for a more novel frame
    np.testing.assert_allclose(w[z > limit], np.exp(-(z[z > limit] - limit)))
    assert np.all(distance_weight(z, None) == 1.0)
