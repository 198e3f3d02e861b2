"""Glove profile / session calibration files and the robust session calibration."""

import json

import numpy as np
import pytest

from handflow.plugins.glove.synthetic import SyntheticGlove
from handflow.plugins.mapping.calibration import (
    DEFAULT_PROFILE,
    CalibrationFileError,
    calibrate_session,
    load_calibration,
    load_profile,
    save,
)
from handflow.plugins.mapping.parallelogram import Parallelogram, fit_intercepts, fit_slopes, robust_extremes


def _session(seed=0):
    """Synthetic session whose true extremes are held for a while (as the guided prompts ask)."""
    rng = np.random.default_rng(seed)
    lo = rng.integers(20, 60, 22)
    hi = rng.integers(180, 240, 22)
    body = rng.uniform(lo + 5, hi - 5, (500, 22))
    held = np.vstack([np.tile(lo, (20, 1)), np.tile(hi, (20, 1))])
    frames = np.rint(np.vstack([body, held]))
    return rng.permutation(frames), lo, hi


def test_robust_extremes_reject_isolated_outliers():
    frames, lo, hi = _session()
    frames[3, 4] = 255  # the other hand pressing a sensor
    frames[7, 4] = 1
    got_lo, got_hi, rejected = robust_extremes(frames, support=5)
    np.testing.assert_array_equal(got_lo, lo)
    np.testing.assert_array_equal(got_hi, hi)
    assert rejected[4] == 2 and rejected.sum() == 2


def test_session_calibration_reproduces_known_extremes():
    frames, lo, hi = _session()
    profile = load_profile(DEFAULT_PROFILE)
    cal = calibrate_session(frames, profile)
    np.testing.assert_array_equal(cal.s_min, lo)
    np.testing.assert_array_equal(cal.s_max, hi)
    assert cal.n_samples == len(frames)


def test_thumb_intercepts_shift_per_session_with_fixed_slopes():
    true = Parallelogram(-3.5, 0.05, 250.0, 240.0, 560.0, 150.0)
    rng = np.random.default_rng(0)
    u, v = rng.uniform(0, 1, 3000), rng.uniform(0, 1, 3000)
    u[:10], v[:10] = [0, 0, 1, 1, 0, 1, 0, 1, 0.5, 0.5], [0, 1, 0, 1, 0, 1, 1, 0, 0, 1]
    u, v = np.tile(u[:10], 5).tolist() + u.tolist(), np.tile(v[:10], 5).tolist() + v.tolist()
    x, y = true.reading(np.array(u), np.array(v))
    x, y = np.r_[x, 300.0], np.r_[y, 20.0]  # one outlier
    para, rejected = fit_intercepts(x, y, true.m13, true.m24)
    np.testing.assert_allclose([para.b1, para.b2, para.b3, para.b4], [250, 240, 560, 150], atol=1e-6)
    assert 1 <= rejected <= 20
    m13, m24 = fit_slopes(x, y)
    assert abs(m13 - true.m13) < 0.15 and abs(m24 - true.m24) < 0.02


def test_roundtrip_yaml_and_json(tmp_path):
    frames = SyntheticGlove().frames(np.linspace(0, 8, 400))
    cal = calibrate_session(frames, load_profile(DEFAULT_PROFILE))
    for name in ("c.yaml", "c.json"):
        save(cal, tmp_path / name)
        assert load_calibration(tmp_path / name) == cal


@pytest.mark.parametrize(
    "content, message",
    [
        ("s_min: [1, 2\n", r"calib.yaml:2: YAML syntax error"),
        ("- just a list\n", "must hold a mapping"),
        ("s_min: [1, 2]\ns_max: [3, 4]\nthumb_intercepts: [1, 2, 3, 4]\n", "need 22 values"),
        (
            "s_min: "
            + json.dumps([50] * 22)
            + "\ns_max: "
            + json.dumps([40] + [200] * 21)
            + "\nthumb_intercepts: [1, 2, 3, 4]\n",
            "thumb_roll",
        ),
        (
            "s_min: "
            + json.dumps([50] * 22)
            + "\ns_max: "
            + json.dumps([200] * 22)
            + "\nthumb_intercepts: [1, 2, 3, 4]\n"
            "colour: blue\n",
            "colour",
        ),
    ],
)
def test_corrupt_calibration_file_gives_clear_error(tmp_path, content, message):
    path = tmp_path / "calib.yaml"
    path.write_text(content)
    with pytest.raises(CalibrationFileError, match=message) as err:
        load_calibration(path)
    assert str(path) in str(err.value)


def test_missing_and_broken_profile(tmp_path):
    with pytest.raises(CalibrationFileError, match="not found.*handflow calibrate"):
        load_profile(tmp_path / "nope.yaml")
    (tmp_path / "p.json").write_text('{"thumb_m13": 1, "thumb_m24": 1, "zero_abduction": {}}')
    with pytest.raises(CalibrationFileError, match="must differ|zero_abduction"):
        load_profile(tmp_path / "p.json")


def test_the_mapping_node_takes_a_new_calibration_file_while_running(tmp_path):
    """docs/tuning.md: a session calibrated anew is set live; one that does not load is refused."""
    from handflow.framework.messages import GloveFrame
    from handflow.framework.runtime.live_params import ParamRefused
    from handflow.framework.testkit.harness import NodeHarness
    from handflow.plugins.mapping.nodes import HumanHandMappingNode

    frames, _, _ = _session(1)
    save(calibrate_session(frames, load_profile(DEFAULT_PROFILE)), tmp_path / "today.yaml")
    (tmp_path / "broken.yaml").write_text("min: [1, 2]\n")
    h = NodeHarness(HumanHandMappingNode, {}, base_dir=tmp_path).setup()
    raw = GloveFrame(sensors=frames[0].astype(np.int64))
    h.send("raw", raw)
    h.set_param("calibration", "today.yaml")
    h.send("raw", raw)
    with pytest.raises(ParamRefused, match=r"(?s)refused by the node: .*broken.yaml:1: s_min"):
        h.set_param("calibration", "broken.yaml")
    h.send("raw", raw)
    before, after, kept = (m.positions for m in h.published["joints"])
    assert not np.allclose(before, after) and np.array_equal(after, kept)
    assert h.node.params.calibration == "today.yaml"
