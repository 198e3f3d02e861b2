"""Commands (calibrate, glove-emulator) and node wrappers through NodeHarness."""

import time

import numpy as np
import pytest

from handflow.framework.messages import GloveFrame, JointState
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.glove.cli import register_calibrate, register_emulator
from handflow.plugins.glove.frames_io import save_frames
from handflow.plugins.glove.node import CyberGloveNode
from handflow.plugins.glove.synthetic import SyntheticGlove
from handflow.plugins.hands.joints import GIFU, HUMAN, SHADOW
from handflow.plugins.mapping.calibration import load_calibration
from handflow.plugins.mapping.nodes import GifuHandMappingNode, HumanHandMappingNode, ShadowHandMappingNode
from tests.conftest import run_command


def test_calibrate_from_mcap_recording_reproduces_min_max(tmp_path, capsys):
    frames = SyntheticGlove().frames(np.linspace(0, 8, 800))
    rec = save_frames(tmp_path / "session.mcap", frames)
    out = tmp_path / "calib.yaml"
    assert run_command(register_calibrate, ["--recording", str(rec), "-o", str(out), "--support", "1"]) == 0
    cal = load_calibration(out)
    np.testing.assert_array_equal(cal.s_min, frames.min(axis=0))
    np.testing.assert_array_equal(cal.s_max, frames.max(axis=0))
    assert "wrote" in capsys.readouterr().out


def test_calibrate_bad_input_exits_2_with_message(tmp_path, capsys):
    out = tmp_path / "c.yaml"
    assert run_command(register_calibrate, ["--recording", str(tmp_path / "none.mcap"), "-o", str(out)]) == 2
    assert "not found" in capsys.readouterr().err
    bad = tmp_path / "profile.yaml"
    bad.write_text("thumb_m13: [\n")
    np.save(tmp_path / "f.npy", np.full((10, 22), 100))
    assert (
        run_command(register_calibrate, ["--recording", str(tmp_path / "f.npy"), "-o", str(out), "--profile", str(bad)])
        == 2
    )
    assert "profile.yaml:2: YAML syntax error" in capsys.readouterr().err
    assert not out.exists()


def test_calibrate_on_a_missing_port_exits_2_before_the_guided_session(tmp_path, capsys, run_handflow):
    out = tmp_path / "c.yaml"
    t0 = time.monotonic()
    assert run_command(register_calibrate, ["--port", "/dev/handflow-no-such-glove", "-o", str(out)]) == 2
    assert time.monotonic() - t0 < 2.0
    err = capsys.readouterr().err
    assert "glove device /dev/handflow-no-such-glove not found" in err and "port: emulator" in err
    assert "Step 1/" not in err and not out.exists()
    proc = run_handflow("calibrate", "--port", "/dev/nonexistent", "-o", str(out))  # the real command
    assert proc.returncode == 2 and "Step 1/" not in proc.stderr and "Traceback" not in proc.stderr


def test_calibrate_on_a_path_that_is_no_serial_port_exits_2_before_the_guided_session(tmp_path, run_handflow):
    """/dev/null exists but cannot be configured as a serial port: refused at once, not after 7 steps."""
    out = tmp_path / "c.yaml"
    t0 = time.monotonic()
    proc = run_handflow("calibrate", "--port", "/dev/null", "-o", str(out))
    assert proc.returncode == 2 and time.monotonic() - t0 < 10.0  # the guided session alone takes 35 s
    assert "glove device /dev/null cannot be opened as a serial port" in proc.stderr
    assert "serial ports on this machine" in proc.stderr and "port: emulator" in proc.stderr
    assert "Step 1/" not in proc.stderr and "Traceback" not in proc.stderr and not out.exists()


def test_calibrate_live_from_emulator(tmp_path, capsys):
    out = tmp_path / "live.json"
    assert run_command(register_calibrate, ["--port", "emulator", "-o", str(out), "--step-seconds", "0.15"]) == 0
    err = capsys.readouterr().err
    assert "Step 1/7" in err and "frames" in err
    assert load_calibration(out).n_samples > 20


def test_emulator_command_prints_path_and_stops(capsys):
    assert run_command(register_emulator, ["--duration", "0.3", "--fault", "garbage@10:5"]) == 0
    assert "ttyCyberGlove" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        run_command(register_emulator, ["--fault", "melt@3"])


def test_glove_node_publishes_frames_and_status_from_embedded_emulator():
    h = NodeHarness(CyberGloveNode, {"port": "emulator", "glove_rate_hz": 200}).setup()
    try:
        for _ in range(60):
            time.sleep(0.01)
            h.tick()
    finally:
        h.teardown()
    frames = h.published["frames"]
    assert len(frames) > 30
    ticks = [f.device_time for f in frames]
    assert ticks == sorted(ticks) and len(set(ticks)) == len(ticks)
    assert all(f.sensors.shape == (22,) and f.status & 0x80 for f in frames)
    states = [s.state for s in h.published["status"]]
    assert states[0] in ("warn", "ok") and "ok" in states
    final = h.node.safe_output()["status"]
    assert final.counters["records"] == final.counters["published"] == len(frames)


def test_mapping_nodes_chain_with_joint_names():
    frames = SyntheticGlove().frames(np.linspace(0, 2, 5))
    human = NodeHarness(HumanHandMappingNode, {}).setup()
    shadow = NodeHarness(ShadowHandMappingNode, {}).setup()
    gifu = NodeHarness(GifuHandMappingNode, {"merge": "pip"}).setup()
    for k, f in enumerate(frames):
        human.send("raw", GloveFrame(sensors=f), stamp_ns=1000 + k)
    assert [m.header.stamp_ns for m in human.published["joints"]] == [1000, 1001, 1002, 1003, 1004]
    for msg in human.published["joints"]:
        shadow.send("joints", msg)
        gifu.send("joints", msg)
    assert human.published["joints"][0].names == HUMAN.names
    assert shadow.published["joints"][-1].names == SHADOW.names and shadow.published["joints"][-1].hand == "shadow"
    assert gifu.published["joints"][-1].names == GIFU.names
    # reordered input joints are matched by name
    msg = human.published["joints"][0]
    order = np.random.default_rng(0).permutation(24)
    shadow.send("joints", JointState(names=[msg.names[i] for i in order], positions=msg.positions[order]))
    np.testing.assert_allclose(shadow.published["joints"][-1].positions, shadow.published["joints"][0].positions)


def test_robot_node_rejects_non_human_joints(caplog):
    shadow = NodeHarness(ShadowHandMappingNode, {}).setup()
    shadow.send("joints", JointState(names=["a"], positions=[0.0]))
    assert not shadow.published["joints"] and "th_abduction" in caplog.text


def test_human_node_missing_calibration_is_clear(tmp_path):
    h = NodeHarness(HumanHandMappingNode, {"calibration": "missing.yaml"}, base_dir=tmp_path)
    with pytest.raises(ValueError, match="missing.yaml' not found"):
        h.setup()
