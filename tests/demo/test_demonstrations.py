"""Demonstration recordings: structure, determinism, the command line, and the shipped examples."""

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from handflow.framework.files.mcap_reader import read_messages, read_report
from handflow.plugins.demo import load_ball_demonstrations, load_cap_demonstrations
from handflow.plugins.demo.cap_turning import CapTurningDemonstrator
from handflow.plugins.demo.cli import register_demo_record
from handflow.plugins.demo.demonstrations import OBSERVATION_NAMES, record_balls, record_cap
from handflow.plugins.hands.joints import GIFU, SHADOW
from handflow.plugins.simulator.metrics import count_swaps
from tests.conftest import run_command

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"


def _cap_structure(path):
    labels = [m for t, m, _ in read_messages(path) if t.endswith("demo/label")]
    joints = [m for t, m, _ in read_messages(path) if t.endswith("sim/joints")]
    assert len(labels) == len(joints) and all(j.names == SHADOW.names for j in joints)
    per_seq = Counter(int(m.data[1]) for m in labels)
    radius = {int(m.data[1]): m.data[0] for m in labels}
    return per_seq, radius, joints


def test_cap_recording_has_radius_and_sequence_per_posture(tmp_path):
    path = tmp_path / "cap.mcap"
    summary = record_cap(path, radii=[0.015, 0.035], sequences=1, seed=1)
    per_seq, radius, joints = _cap_structure(path)
    assert sorted(radius.values()) == [0.015, 0.035]
    assert all(30 <= n <= 45 for n in per_seq.values()) and summary.postures == sum(per_seq.values())
    # collision correction: the closed small-cap postures differ from the free-air targets
    closed = max(j.positions[SHADOW.index("MFJ3")] for j in joints[: per_seq[0]])
    assert closed < CapTurningDemonstrator().closure(0.015) - 0.2
    assert read_report(path).metadata["handflow.demo"]["task"] == "cap_turning"


def test_same_seed_gives_the_same_recording(tmp_path):
    a, b, c = (tmp_path / f"{n}.mcap" for n in "abc")
    record_cap(a, radii=[0.02], sequences=1, seed=5)
    record_cap(b, radii=[0.02], sequences=1, seed=5)
    record_cap(c, radii=[0.02], sequences=1, seed=6)
    assert a.read_bytes() == b.read_bytes()
    assert a.read_bytes() != c.read_bytes()


def test_ball_recording_has_twenty_dimensional_observations_per_swap_cycle(tmp_path):
    path = tmp_path / "balls.mcap"
    summary = record_balls(path, cycles=1, seed=0, rate_hz=10)
    obs = [m for t, m, _ in read_messages(path) if t.endswith("demo/observation")]
    joints = [m for t, m, _ in read_messages(path) if t.endswith("sim/joints")]
    assert summary.frames == len(joints) == 40  # one swap cycle = two 2-s hand cycles at 10 Hz
    assert len(obs) == summary.observations > 30 and summary.swaps >= 1
    assert obs[0].names == OBSERVATION_NAMES and obs[0].data.size == 20
    assert joints[0].names == GIFU.names
    ((meta, observations, names),) = load_ball_demonstrations(path)
    assert names == OBSERVATION_NAMES and observations.shape == (summary.observations, 20)
    assert meta["swap_cycle"] == 0 and set(meta["hand_cycle"]) == {0, 1}
    assert np.all(np.diff(meta["time_s"]) > 0) and 0 < meta["hand_phase"].min() and meta["hand_phase"].max() <= 1


def test_cap_loader_returns_each_sequence_with_its_radius(tmp_path):
    path = tmp_path / "cap.mcap"
    record_cap(path, radii=[0.02, 0.03], sequences=2, seed=2)
    loaded = load_cap_demonstrations(path)
    assert [m["sequence"] for m, _, _ in loaded] == [0, 1, 2, 3]
    assert [m["radius_m"] for m, _, _ in loaded] == [0.02, 0.02, 0.03, 0.03]
    assert all(y.shape[1] == 24 and 30 <= y.shape[0] <= 45 and names == SHADOW.names for _, y, names in loaded)


def test_loaders_say_what_is_wrong_with_the_file(tmp_path):
    with pytest.raises(ValueError, match="demo-record"):
        load_cap_demonstrations(tmp_path / "missing.mcap")
    path = tmp_path / "cap.mcap"
    record_cap(path, radii=[0.025], sequences=1, seed=0)
    with pytest.raises(ValueError, match="demo/observation"):
        load_ball_demonstrations(path)


def test_cap_release_uncurls_the_fingertips_before_opening_the_rest():
    demo = CapTurningDemonstrator()
    var = demo.variation(np.random.default_rng(0))
    keys = demo.key_postures(0.02, var)
    release = demo.released(keys)
    for f in ("FF", "MF", "RF", "LF"):
        assert release[SHADOW.index(f"{f}J2")] == keys[3][SHADOW.index(f"{f}J2")]  # open
        assert release[SHADOW.index(f"{f}J3")] == keys[2][SHADOW.index(f"{f}J3")]  # still closed
    d_start = 1.0 - var.fractions[3]
    mid = demo.targets(np.array([d_start + demo.release_fraction * var.fractions[3]]), 0.02, var)[0]
    np.testing.assert_allclose(mid, release, atol=1e-9)
    with pytest.raises(ValueError, match="release_fraction"):
        CapTurningDemonstrator(release_fraction=1.0)


def test_command_rejects_bad_input_with_exit_code_2(tmp_path, capsys):
    assert run_command(register_demo_record, ["cap", "--out", str(tmp_path / "x.txt")]) == 2
    assert ".mcap" in capsys.readouterr().err
    assert run_command(register_demo_record, ["cap", "--out", str(tmp_path / "x.mcap"), "--radii", "25"]) == 2
    assert "cm" in capsys.readouterr().err
    assert not (tmp_path / "x.mcap").exists()


def test_command_records_with_a_progress_line(tmp_path, capsys):
    assert (
        run_command(
            register_demo_record, ["cap", "--out", str(tmp_path / "c.mcap"), "--radii", "2.5", "--sequences", "1"]
        )
        == 0
    )
    assert "sequence 1/1" in capsys.readouterr().err


@pytest.mark.skipif(not (RECORDINGS / "cap_turning_demo.mcap").exists(), reason="example recording not present")
def test_shipped_cap_example_covers_all_radii():
    per_seq, radius, _ = _cap_structure(RECORDINGS / "cap_turning_demo.mcap")
    counts = Counter(radius.values())
    assert sorted(counts) == [0.015, 0.02, 0.025, 0.03, 0.035]
    assert all(5 <= n <= 9 for n in counts.values())
    assert all(30 <= n <= 45 for n in per_seq.values())


@pytest.mark.skipif(not (RECORDINGS / "ball_swap_demo.mcap").exists(), reason="example recording not present")
def test_shipped_ball_example_swaps_the_balls_over_four_swap_cycles():
    cycles = load_ball_demonstrations(RECORDINGS / "ball_swap_demo.mcap")
    assert len(cycles) == 4 and all(obs.shape[1] == 20 and obs.shape[0] > 60 for _, obs, _ in cycles)
    tracked = np.vstack([obs for _, obs, _ in cycles])
    assert count_swaps(tracked[:, 16:18], tracked[:, 18:20]) >= 6  # tracked balls: ~one swap per hand cycle
