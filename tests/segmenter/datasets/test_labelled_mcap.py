"""``handflow dataset``: labelled MCAP recordings → continuous recordings (plugins/segmenter/datasets/_labelled_mcap.py)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from handflow.framework.commands.inspect import summarize
from handflow.framework.files.mcap_writer import McapWriter
from handflow.framework.messages import JointState, Label
from handflow.plugins.segmenter.cli import known_segments, register_dataset
from handflow.plugins.segmenter.datasets import load_recordings
from tests.conftest import handflow, run_command

CLASSES = ["grasp", "pinch", "wave"]
NAMES = ["A", "B", "C"]
RATE = 50


def _session(path, rounds=3, cue_s=1.0, rest_s=0.5, interrupt=False, cues=True):
    """A session as ``handflow collect`` records it: a 3-joint stream and the cue topic."""
    t0 = 10**12
    marks = [(t0, "rest", -1)]
    t = t0 + int(0.5e9)
    k = 0
    for r in range(rounds):
        for c in np.random.default_rng([0, r]).permutation(3):
            marks.append((t, CLASSES[c], k))
            marks.append((t + int(cue_s * 1e9), "rest", k))
            t += int((cue_s + rest_s) * 1e9)
            k += 1
    if interrupt:  # a repetition started and withdrawn at its own stamp (Ctrl-C)
        marks += [(t, "grasp", k), (t, "", -1)]
        t += int(0.6e9)
    marks.append((t, "", -1))
    with McapWriter(path, flush_interval_s=None) as w:
        for n, stamp in enumerate(range(t0, t, 10**9 // RATE)):
            msg = JointState(names=NAMES, positions=np.sin([n / 7, n / 11, n / 13]))
            msg.header.stamp_ns = stamp
            w.write("handflow/g/shadow/joints", msg, stamp)
        if cues:
            for stamp, label, index in marks:
                msg = Label(label=label, index=index, classes=CLASSES)
                msg.header.stamp_ns = stamp
                w.write("handflow/g/cue/labels", msg, stamp)
    return path


def test_a_cued_session_becomes_rounds_of_continuous_recordings(tmp_path, capsys):
    rec = _session(tmp_path / "s.mcap", interrupt=True)
    assert run_command(register_dataset, [str(rec), "--topic", "shadow/joints", "--out", str(tmp_path / "d.npz")]) == 0
    out = capsys.readouterr().out
    assert "wrote 3 recording(s)" in out
    for c in CLASSES:  # 3 repetitions of 50 frames; the withdrawn one is not counted
        assert f"{c}: 3 repetition(s), 150 frames\n" in out, out
    assert re.search(r"^rest: 10 repetition\(s\), \d+ frames \(unknown: no model is trained for it\)$", out, re.M), out
    data = load_recordings(tmp_path / "d.npz")
    assert data.class_names == [*CLASSES, "rest"] and data.known_classes == CLASSES
    assert [r.name for r in data.recordings] == ["s_r0", "s_r1", "s_r2"]
    for r in data.recordings:  # every recording holds one whole round: 50 frames of each class
        counts = np.bincount(r.y[r.y >= 0], minlength=4)
        assert list(counts[:3]) == [50, 50, 50], counts
    assert (data.recordings[-1].y == -1).sum() >= 30  # the withdrawn repetition is unlabelled, not grasp
    assert list(known_segments(str(tmp_path / "d.npz"), None)) == CLASSES  # rest is not trained
    labels = summarize(str(rec))["labels"]["handflow/g/cue/labels"]
    assert labels["grasp"]["intervals"] == 3 and labels["rest"]["intervals"] == 10


def test_labels_from_an_interval_csv(tmp_path, capsys):
    rec = _session(tmp_path / "plain.mcap", rounds=2, cues=False)
    csv = tmp_path / "intervals.csv"
    csv.write_text("start_s,end_s,label\n0.5,1.5,grasp\n2,3,pinch\n3.5,4.5,wave\n5,6,grasp\n6.5,7.5,pinch\n8,9,wave\n")
    args = [str(rec), "--topic", "shadow/joints", "--labels", str(csv), "--out", str(tmp_path / "d.npz")]
    assert run_command(register_dataset, args) == 0
    assert "wrote 2 recording(s)" in capsys.readouterr().out
    data = load_recordings(tmp_path / "d.npz")
    assert [int((r.y == 0).sum()) for r in data.recordings] == [50, 50]
    assert summarize(str(rec))["labels"] == {}


@pytest.mark.parametrize(
    "extra, csv, message",
    [
        ([], None, "carries no labels (no Label topic); record it with `handflow collect` or pass --labels"),
        ([], "0,1,grasp\n5,99,wave\n", "intervals.csv:2: interval 5–99 s ends after the labelled stream"),
        ([], "0,2,grasp\n1,3,wave\n", "intervals.csv:2: interval 1–3 s overlaps 0–2 s of line 1"),
        (["--classes", "grasp,fist"], "0,2,grasp\n", "class(es) ['fist'] have no repetition"),
    ],
)
def test_bad_labels_stop_with_what_to_change(tmp_path, capsys, extra, csv, message):
    rec = _session(tmp_path / "plain.mcap", rounds=1, cues=False)
    args = [str(rec), "--topic", "shadow/joints", "--out", str(tmp_path / "d.npz"), *extra]
    if csv is not None:
        (tmp_path / "intervals.csv").write_text(csv)
        args += ["--labels", str(tmp_path / "intervals.csv")]
    assert run_command(register_dataset, args) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "d.npz").exists()


def test_the_command_warns_about_few_repetitions_and_errs_without_traceback(tmp_path):
    rec = _session(tmp_path / "s.mcap", rounds=2)
    proc = handflow("dataset", str(rec), "--topic", "shadow/joints", "--out", str(tmp_path / "d.npz"))
    assert proc.returncode == 0, proc.stderr
    assert "warning: class grasp has only 2 repetition(s); record at least 3" in proc.stderr
    proc = handflow("dataset", str(rec), "--topic", "shadow/nothing", "--out", str(tmp_path / "e.npz"))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "holds no message on shadow/nothing; name the recorded stream with --topic" in proc.stderr
