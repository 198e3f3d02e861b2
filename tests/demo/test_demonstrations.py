"""Demonstration recordings: structure, determinism, the command line, and the shipped examples."""
import argparse
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from framework.recording import read_messages, read_report
from plugins.demo.cap_turning import CapTurningDemonstrator
from plugins.demo.cli import register_demo_record
from plugins.demo.demonstrations import OBSERVATION_NAMES, record_balls, record_cap
from plugins.mapping.hands import GIFU, SHADOW

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


def test_ball_recording_has_twenty_dimensional_observations(tmp_path):
    path = tmp_path / "balls.mcap"
    summary = record_balls(path, cycles=1, seed=0, rate_hz=10)
    obs = [m for t, m, _ in read_messages(path) if t.endswith("demo/observation")]
    joints = [m for t, m, _ in read_messages(path) if t.endswith("sim/joints")]
    assert summary.frames == len(joints) == 20 and len(obs) == summary.observations > 0
    assert obs[0].names == OBSERVATION_NAMES and obs[0].data.size == 20
    assert joints[0].names == GIFU.names


def _run(argv):
    parser = argparse.ArgumentParser()
    register_demo_record(parser)
    args = parser.parse_args(argv)
    return args.func(args)


def test_command_rejects_bad_input_with_exit_code_2(tmp_path, capsys):
    assert _run(["cap", "--out", str(tmp_path / "x.txt")]) == 2
    assert ".mcap" in capsys.readouterr().err
    assert _run(["cap", "--out", str(tmp_path / "x.mcap"), "--radii", "25"]) == 2
    assert "cm" in capsys.readouterr().err
    assert not (tmp_path / "x.mcap").exists()


def test_command_records_with_a_progress_line(tmp_path, capsys):
    assert _run(["cap", "--out", str(tmp_path / "c.mcap"), "--radii", "2.5", "--sequences", "1"]) == 0
    assert "sequence 1/1" in capsys.readouterr().err


@pytest.mark.skipif(not (RECORDINGS / "cap_turning_demo.mcap").exists(), reason="example recording not present")
def test_shipped_cap_example_covers_all_radii():
    per_seq, radius, _ = _cap_structure(RECORDINGS / "cap_turning_demo.mcap")
    counts = Counter(radius.values())
    assert sorted(counts) == [0.015, 0.02, 0.025, 0.03, 0.035]
    assert all(5 <= n <= 9 for n in counts.values())
    assert all(30 <= n <= 45 for n in per_seq.values())


@pytest.mark.skipif(not (RECORDINGS / "ball_swap_demo.mcap").exists(), reason="example recording not present")
def test_shipped_ball_example_has_observations():
    obs = [m for t, m, _ in read_messages(RECORDINGS / "ball_swap_demo.mcap") if t.endswith("demo/observation")]
    assert len(obs) > 100 and np.all([o.data.size == 20 for o in obs])
