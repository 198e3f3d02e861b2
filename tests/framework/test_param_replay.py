"""A live run's parameter changes, recorded, applied again by a lock-step replay (docs/tuning.md): the replay
gives the live run's labels (`handflow compare` exit 0); without the changes it does not."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from handflow.framework import keys
from handflow.framework.files.mcap_reader import iter_recording, read_messages
from handflow.framework.files.mcap_writer import McapWriter
from handflow.framework.messages import Header
from handflow.framework.runtime.discovery import join, live_runs

pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]
GRAPH = REPO / "configs" / "demo_segment_only.yaml"  # the flagship's segmenter alone, fed shadow/joints
JOINTS = "handflow/gestures/shadow/joints"
FRAMES = 300  # 7.5 s of the shipped gesture recording, at 40 Hz


def handflow(*args: str, cwd: Path, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", *args], cwd=cwd, env=env, capture_output=True, text=True
    )


def test_lockstep_replay_applies_the_recorded_changes_and_gives_the_live_labels(tmp_path, monkeypatch):
    take = tmp_path / "take.mcap"
    with McapWriter(take) as writer:
        for i, rm in enumerate(iter_recording(REPO / "recordings" / "gestures.mcap", [JOINTS])):
            if i == FRAMES:
                break
            msg = rm.decode()
            msg.header = Header("shadow", i + 1, rm.publish_time_ns)
            writer.write(JOINTS, msg, log_time_ns=rm.log_time_ns)
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    env = dict(os.environ)
    live = subprocess.Popen(  # the live run: the segmenter fed at the recorded pace, tuned meanwhile
        [sys.executable, "-m", "handflow.framework.cli", "replay", str(take), "--into", str(GRAPH)]
        + ["--record", "live.mcap"],
        cwd=tmp_path,
        env=env,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 180  # a busy machine takes a while to import the segmenter
    while not live_runs() and time.monotonic() < deadline:
        time.sleep(0.1)
    session, _ = join()  # asks as `handflow param set` does, without a CLI start between the changes
    request = keys.param_request_key("demo_segment_only", "local", "segmenter")

    def ask(body: dict) -> list[dict]:
        return [json.loads(r.ok.payload.to_bytes()) for r in session.get(request, payload=json.dumps(body)) if r.ok]

    while not any(a["ok"] for a in ask({"op": "get"})):
        assert time.monotonic() < deadline, "the segmenter did not come up"
    answers = []
    for value in (4.0, 0.5, 2.0):
        time.sleep(0.8)
        answers += ask({"op": "set", "key": "background_factor", "value": value})
    session.close()
    _, err = live.communicate(timeout=120)
    assert live.returncode == 0, err
    assert [a.get("params", {}).get("background_factor") for a in answers] == [4.0, 0.5, 2.0], answers
    changes = [m for t, m, _ in read_messages(tmp_path / "live.mcap") if t == keys.params_key("demo_segment_only")]
    assert [c.value for c in changes] == ["4.0", "0.5", "2.0"]

    replayed = handflow(
        "replay", "live.mcap", "--into", str(GRAPH), "--lockstep", "--record", "replayed.mcap", cwd=tmp_path, env=env
    )
    assert replayed.returncode == 0, replayed.stderr
    assert "applying 3 recorded parameter change(s)" in replayed.stderr
    same = handflow("compare", "live.mcap", "replayed.mcap", "--topics", "segmenter/labels", cwd=tmp_path, env=env)
    assert same.returncode == 0, same.stdout + same.stderr

    stripped = handflow(
        "replay", "live.mcap", "--into", str(GRAPH), "--lockstep", "--no-param-changes", "--record", "stripped.mcap",
        cwd=tmp_path, env=env,
    )  # fmt: skip
    assert stripped.returncode == 0, stripped.stderr
    differs = handflow("compare", "live.mcap", "stripped.mcap", "--topics", "segmenter/labels", cwd=tmp_path, env=env)
    assert differs.returncode == 1, differs.stdout
