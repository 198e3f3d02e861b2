"""``handflow collect``: cued collection into one MCAP with its cue topic (framework/commands/collect.py)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

from handflow.framework.commands.collect import register
from handflow.framework.commands.inspect import summarize
from handflow.framework.recorder.cues import recorded_cues
from tests.conftest import handflow, run_command

CUES = "handflow/collect_gestures/cue/labels"


def test_bad_input_is_refused_before_the_graph_starts(tmp_path, monkeypatch, capsys):
    proc = handflow(
        "collect",
        "collect_gestures",
        "--topic",
        "shadow/jionts",
        "--classes",
        "grasp,pinch",
        "--reps",
        "1",
        cwd=tmp_path,
    )
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "--topic shadow/jionts: graph 'collect_gestures' publishes no such topic; it publishes" in proc.stderr
    assert "shadow/joints" in proc.stderr and "started" not in proc.stderr
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "session.mcap").write_bytes(b"keep me")
    monkeypatch.chdir(tmp_path)
    for extra, message in (
        ([], "out/session.mcap exists; pass --append to add rounds to that session, or another --out"),
        (["--out", "out/none.mcap", "--append"], "--append: out/none.mcap does not exist"),
        (["--classes", "grasp,rest"], "'rest', 'unknown', '' are reserved"),
    ):
        args = ["collect_gestures", "--topic", "shadow/joints", "--classes", "grasp,pinch", "--reps", "1"]
        assert run_command(register, args + extra) == 2
        assert message in capsys.readouterr().err
    assert (tmp_path / "out" / "session.mcap").read_bytes() == b"keep me"


@pytest.mark.slow
def test_ctrl_c_keeps_finished_repetitions_and_append_adds_rounds(tmp_path):
    args = [sys.executable, "-m", "handflow.framework.cli", "collect", "collect_gestures", "--topic", "shadow/joints"]
    args += ["--classes", "grasp,pinch,wave", "--cue-s", "1.5", "--rest-s", "0.5", "--lead-s", "0.5"]
    proc = subprocess.Popen(
        [*args, "--reps", "2"], cwd=tmp_path, stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    seen = []
    deadline = time.monotonic() + 90
    while len([line for line in seen if "perform" in line]) < 3:  # Ctrl-C during the third repetition
        assert time.monotonic() < deadline and proc.poll() is None, "".join(seen)
        seen.append(proc.stderr.readline())
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "recorded 2 repetition(s)" in out and "stopped by Ctrl-C; finished repetitions kept" in out
    session = tmp_path / "out" / "session.mcap"
    classes, finished, next_round = recorded_cues(session, CUES)
    assert (classes, finished, next_round) == (["grasp", "pinch", "wave"], 2, 1)
    labels = summarize(str(session))["labels"][CUES]
    assert sum(v["intervals"] for k, v in labels.items() if k != "rest") == 2  # the third was withdrawn

    done = subprocess.run([*args, "--reps", "1", "--append"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "recorded 3 repetition(s) (grasp 1, pinch 1, wave 1) to out/session.mcap (appended)" in done.stdout
    assert recorded_cues(session, CUES)[1:] == (5, 2)
    summary = summarize(str(session))
    counts = {t["topic"]: t["count"] for t in summary["topics"]}
    assert counts["handflow/collect_gestures/shadow/joints"] > 50 * 8  # both parts' frames
    performed = summary["labels"]["handflow/collect_gestures/glove/performed"]
    assert sum(v["intervals"] for k, v in performed.items() if k != "rest") == 6  # the withdrawn one was performed
    assert not list(tmp_path.glob("out/*.part.mcap"))
