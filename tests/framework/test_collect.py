"""``handflow collect``: cued collection into one MCAP with its cue topic (framework/commands/collect.py)."""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import pytest
from websockets.exceptions import ConnectionClosed

from handflow.framework.commands.collect import register
from handflow.framework.commands.inspect import summarize
from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.recorder.cues import recorded_cues
from handflow.framework.ros2.types import decode_cdr
from tests.conftest import handflow, run_command
from tests.foxglove_client import FoxgloveClient, handflow_with_foxglove

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


def _monitor_and_echo(cwd, env) -> tuple[subprocess.CompletedProcess, subprocess.CompletedProcess]:
    """``handflow monitor --once`` and ``handflow echo cue/labels -n 1`` on the running session."""
    monitored = handflow("monitor", "--once", "--json", "--listen", "4", cwd=cwd, env=env)
    return monitored, handflow("echo", "cue/labels", "-n", "1", "--json", cwd=cwd, env=env, timeout=30)


@pytest.mark.slow
def test_the_cue_topic_shows_in_monitor_echo_and_foxglove_as_a_user_sees_it(tmp_path):
    """The cues of a running ``handflow collect --foxglove``: ``handflow monitor`` lists the ``Label`` topic with
    its last cue, ``handflow echo cue/labels`` prints cues, and a real Foxglove client sees the channel
    advertised with the Label schema and receives messages that decode to the cued classes, with no warning or
    error status; the client saw the cues the session recorded, in order."""
    pytest.importorskip("foxglove")
    env = dict(os.environ, HANDFLOW_RUN_DIR=str(tmp_path / "runs"))
    classes = ["grasp", "pinch", "wave"]
    args = ["collect", "collect_gestures", "--topic", "shadow/joints", "--classes", ",".join(classes), "--reps", "1"]
    proc, port = handflow_with_foxglove([*args, "--cue-s", "3", "--rest-s", "1", "--lead-s", "3"], env, tmp_path)
    seen, monitored, echoed = [], None, None
    try:
        with FoxgloveClient(port, timeout=60) as fox:
            channel = None
            while channel is None:  # advertised with the first cue
                advertised = fox.next("advertise", timeout=60)["channels"]
                channel = next((c for c in advertised if c["topic"] == "/" + CUES), None)
            fox.send(op="subscribe", subscriptions=[{"id": 1, "channelId": channel["id"]}])
            # monitor and echo run while the client reads, as beside an open Foxglove app: a refused subscription
            # (docs/foxglove.md, "Topics") is sent again at once, not after them
            with ThreadPoolExecutor(1) as pool:
                commands = pool.submit(_monitor_and_echo, tmp_path, env)
                with contextlib.suppress(ConnectionClosed):  # until the session ends and its bridge closes
                    while True:
                        frame = fox.recv(timeout=60)
                        if isinstance(frame, bytes) and frame[0] == 1 and int.from_bytes(frame[1:5], "little") == 1:
                            seen.append(decode_cdr(frame[13:], "handflow.Label"))
                monitored, echoed = commands.result()
    finally:
        try:
            _, err = proc.communicate(timeout=60)  # the session ends by itself
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
    assert proc.returncode == 0, err
    assert channel["schemaName"].endswith("Label") and channel["encoding"] == "cdr", channel
    assert fox.problems() == [], fox.problems()
    # what the Foxglove client received: the cues with the classes of the session, in the recorded order
    assert seen and all(m.classes == classes for m in seen), seen
    recorded = [rm.decode() for rm in iter_recording(tmp_path / "out" / "session.mcap", [CUES])]
    shown = [(m.label, m.index, m.header.stamp_ns) for m in seen]
    cued = [(m.label, m.index, m.header.stamp_ns) for m in recorded]
    assert shown == cued[cued.index(shown[0]) :][: len(shown)], (shown, cued)  # none lost, none made up
    assert set(classes) <= {m.label for m in seen}  # every repetition's cue reached it
    # monitor: the Label topic, counted, its last value a cue
    assert monitored.returncode == 0, monitored.stderr
    topic = next(t for t in json.loads(monitored.stdout)["topics"] if t["topic"] == CUES)
    assert topic["type"] == "handflow.Label" and topic["count"] >= 1, topic
    assert re.match(r"label='(grasp|pinch|wave|rest)' index=-?\d+ classes=\[3\]", topic["last"]), topic
    # echo: the topic fed from outside the graph is a topic like any other
    assert echoed.returncode == 0, echoed.stderr
    cue = json.loads(echoed.stdout)
    assert cue["type"] == "handflow.Label" and cue["classes"] == classes and cue["label"] in [*classes, "rest"], cue
