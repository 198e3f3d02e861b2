"""First mapping (raw → human model) properties and the robot mappings."""

import numpy as np
import pytest

from handflow.plugins.glove.synthetic import HandMotion, SyntheticGlove
from handflow.plugins.hands.joints import GIFU, HUMAN, SHADOW
from handflow.plugins.hands.sensors import SENSOR_NAMES, sensor_index
from handflow.plugins.mapping.calibration import DEFAULT_CALIBRATION, DEFAULT_PROFILE, load_calibration, load_profile
from handflow.plugins.mapping.human import LINEAR_JOINTS, HumanHandMapping
from handflow.plugins.mapping.robot import GifuHandMapping, ShadowHandMapping
from handflow.plugins.mapping.thumb import thumb_to_shadow


@pytest.fixture(scope="module")
def mapping():
    return HumanHandMapping(load_profile(DEFAULT_PROFILE), load_calibration(DEFAULT_CALIBRATION))


@pytest.fixture(scope="module")
def raw():
    rng = np.random.default_rng(0)
    return rng.integers(1, 256, (2000, 22))


def test_joint_limits_respected_for_any_raw_input(mapping, raw):
    q = mapping.map(raw)
    assert q.shape == (2000, 24) and np.isfinite(q).all()
    assert np.all(q >= HUMAN.lower - 1e-12) and np.all(q <= HUMAN.upper + 1e-12)
    s = ShadowHandMapping().map(q)
    assert np.all(s >= SHADOW.lower - 1e-12) and np.all(s <= SHADOW.upper + 1e-12)
    g = GifuHandMapping().map(q)
    assert np.all(g >= GIFU.lower - 1e-12) and np.all(g <= GIFU.upper + 1e-12)


@pytest.mark.parametrize("sensor", list(LINEAR_JOINTS))
def test_monotonic_in_each_flex_sensor(mapping, sensor):
    base = np.full((256, 22), 120.0)
    base[:, sensor_index(sensor)] = np.arange(256)
    q = mapping.map(base)[:, HUMAN.index(LINEAR_JOINTS[sensor])]
    assert np.all(np.diff(q) >= 0) and q[-1] > q[0]


def test_thumb_is_monotonic_along_the_parallelogram_axes(mapping):
    para = mapping.parallelogram
    u = np.linspace(0, 1, 50)
    x, y = para.reading(u, np.full(50, 0.5))
    raw = np.full((50, 22), 120.0)
    raw[:, sensor_index("thumb_roll")], raw[:, sensor_index("thumb_abduction")] = x, y
    q = mapping.map(raw)
    assert np.all(np.diff(q[:, HUMAN.index("th_roll")]) > 0)
    assert np.ptp(q[:, HUMAN.index("th_abduction")]) < 1e-9


def test_index_and_little_spread_equal_in_magnitude(mapping, raw):
    q = mapping.map(raw)
    ff, lf = q[:, HUMAN.index("ff_spread")], q[:, HUMAN.index("lf_spread")]
    inside = (np.abs(ff) < HUMAN.upper[HUMAN.index("ff_spread")] - 1e-9) & (
        ff > HUMAN.lower[HUMAN.index("ff_spread")] + 1e-9
    )
    np.testing.assert_allclose(np.abs(ff[inside]), np.abs(lf[inside]), atol=1e-12)


def test_spreading_opens_the_hand(mapping):
    raw = np.full((2, 22), 120.0)
    spread = [sensor_index(n) for n in ("index_middle_abduction", "middle_ring_abduction", "ring_little_abduction")]
    raw[0, spread] = 210  # near the zero level: fingers together
    raw[1, spread] = 60  # unbent: wide spread
    q = mapping.map(raw)
    ff = HUMAN.index("ff_spread")
    assert q[1, ff] < q[0, ff]  # index moves away from the little finger (negative in its convention)


def test_inverse_reproduces_synthetic_postures(mapping):
    q = HandMotion(seed=2).joints(np.linspace(0, 8, 200))
    np.testing.assert_allclose(mapping.map(mapping.inverse(q)), q, atol=1e-9)


def test_rejects_wrong_frame_width(mapping):
    with pytest.raises(ValueError, match="22 sensor values"):
        mapping.map(np.zeros((3, 21)))


def test_shadow_mapping_copies_joints_and_maps_thumb():
    q = HandMotion(seed=1).joints(np.linspace(0, 4, 40))
    s = ShadowHandMapping().map(q)
    np.testing.assert_allclose(s[:, SHADOW.index("FFJ3")], np.clip(q[:, HUMAN.index("ff_mcp")], *np.deg2rad([-15, 90])))
    t0, t1 = thumb_to_shadow(q[:, HUMAN.index("th_abduction")], q[:, HUMAN.index("th_roll")])
    np.testing.assert_allclose(
        s[:, SHADOW.index("THJ4")], np.clip(t1, SHADOW.lower[SHADOW.index("THJ4")], SHADOW.upper[SHADOW.index("THJ4")])
    )


def test_gifu_mapping_merges_pip_dip():
    q = HandMotion(seed=1).joints(np.linspace(0, 4, 40))
    g = GifuHandMapping("mean").map(q)
    assert g.shape == (40, 20)
    np.testing.assert_allclose(g[:, GIFU.index("MF_J3")], g[:, GIFU.index("MF_J4")])
    merged = 0.5 * (q[:, HUMAN.index("mf_pip")] + q[:, HUMAN.index("mf_dip")])
    np.testing.assert_allclose(g[:, GIFU.index("MF_J3")], np.clip(merged, 0, np.pi / 2))
    with pytest.raises(ValueError, match="merge must be one of"):
        GifuHandMapping("median")


def test_synthetic_glove_frames_are_wire_values():
    frames = SyntheticGlove(noise=1.0).frames(np.linspace(0, 4, 100))
    assert frames.shape == (100, len(SENSOR_NAMES)) and frames.min() >= 1 and frames.max() <= 255
