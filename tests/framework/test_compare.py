"""``handflow compare`` on real recordings: equal, differing, only in one, bad input (exit 0/1/2)."""

from __future__ import annotations

import json
import signal
import time

import numpy as np
import pytest

from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.files.mcap_writer import McapWriter
from tests.framework._rec_helpers import REPO, chain, handflow, start, unique, wait_until, write_graph

GESTURES = REPO / "recordings" / "gestures.mcap"  # shipped, old style: JSON, no leading '/'


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    """A recording of a real 3-process chain."""
    tmp = tmp_path_factory.mktemp("compare")
    path = tmp / "live.mcap"
    res = handflow("run", str(chain(tmp / "g.yaml", unique("cmp"))), "--duration", "1", "--record", str(path))
    assert res.returncode == 0, res.stderr
    return path


def _compare(*args: str) -> tuple[int, dict | str, str]:
    res = handflow("compare", *map(str, args))
    return res.returncode, json.loads(res.stdout) if "--json" in args else res.stdout, res.stderr


def test_a_recording_equals_itself_and_a_migrated_copy(live, tmp_path):
    code, out, _ = _compare(live, live)
    assert code == 0 and "equal: 2 topic(s)" in out and "scale/out" in out
    migrated = tmp_path / "gestures_cdr.mcap"  # old JSON recording vs its CDR rewrite: the same messages
    assert handflow("migrate", str(GESTURES), str(migrated)).returncode == 0
    code, out, _ = _compare(GESTURES, migrated, "--json")
    assert code == 0 and out["equal"]
    assert {t["topic"]: t["equal"] for t in out["topics"]} == {
        "glove/frames": 3600,
        "script/truth": 20,
        "shadow/joints": 3600,
    }


def test_differences_are_counted_per_topic_by_stamp(live, tmp_path):
    changed = tmp_path / "changed.mcap"
    records = list(iter_recording(live))
    scale = [i for i, rm in enumerate(records) if rm.topic.endswith("/scale/out")]
    altered, dropped = scale[3], scale[-1]
    with McapWriter(changed) as w:
        for i, rm in enumerate(records):
            if i == dropped:
                continue
            msg = rm.decode()
            if i == altered:
                msg.data = msg.data + np.float64(1e-12)  # the smallest change counts
            w.write(rm.topic, msg, rm.log_time_ns)
        extra = records[scale[0]].decode()
        extra.header.stamp_ns += 1  # a stamp A does not have
        w.write(records[scale[0]].topic, extra)
    code, out, _ = _compare(live, changed, "--json")
    assert code == 1 and not out["equal"]
    by_topic = {t["topic"]: t for t in out["topics"]}
    n = len(scale)
    assert by_topic["scale/out"] | {"first_difference_ns": 0} == {
        "topic": "scale/out",
        "equal": n - 2,
        "differing": 1,
        "only_a": 1,
        "only_b": 1,
        "first_difference_ns": 0,
    }
    assert by_topic["scale/out"]["first_difference_ns"] == records[scale[0]].publish_time_ns + 1  # the extra one
    assert by_topic["source/out"]["differing"] == by_topic["source/out"]["only_a"] == 0
    code, table, _ = _compare(live, changed, "--topics", "source/*")
    assert code == 0 and "scale/out" not in table
    code, table, _ = _compare(live, changed)
    assert code == 1 and "different: scale/out" in table


def test_bad_input_exits_2_with_what_is_wrong_and_truncated_files_compare_what_was_recovered(live, tmp_path):
    code, _, err = _compare(live, tmp_path / "missing.mcap")
    assert code == 2 and "cannot read recording" in err and "missing.mcap" in err and "Traceback" not in err
    text = tmp_path / "notes.mcap"
    text.write_text("not a recording\n")
    code, _, err = _compare(text, live)
    assert code == 2 and "not an MCAP file" in err and "Traceback" not in err
    code, _, err = _compare(live, live, "--topics", "nobody/*")
    assert code == 2 and "no topic matching nobody/*" in err
    cut = tmp_path / "cut.mcap"
    data = live.read_bytes()
    cut.write_bytes(data[: len(data) // 3])  # the tail lost, as after a kill -9 (past the summary and a chunk)
    code, out, err = _compare(live, cut, "--json")
    assert code == 1 and "truncated" in err and "Traceback" not in err
    assert out["files"][1]["recovered"] and sum(t["only_a"] for t in out["topics"]) > 0
    assert sum(t["differing"] for t in out["topics"]) == 0


REPLAY_TARGET = """external: {source/out: Array}
nodes:
  - id: scale
    plugin: basic.transform
    params: {gain: 2.0}
    inputs: {in: source/out}
  - id: sink
    plugin: basic.sink
    inputs: {in: scale/out}
"""


@pytest.mark.slow
def test_a_faithful_lockstep_replay_compares_equal_by_default_also_after_a_restart(tmp_path, monkeypatch):
    """The recording holds a live change (replayed) and a --restart change of the sink (not replayed; its
    outputs are none): the data topics are equal, exit 0; the runtime's own topics differ when asked for."""
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    graph = chain(tmp_path / "g.yaml", unique("faithful"))
    run = start("run", str(graph), "--record", str(tmp_path / "live.mcap"), cwd=tmp_path)
    try:
        wait_until(lambda: handflow("param", "get", "sink", cwd=tmp_path).returncode == 0, 60, "the graph")
        assert handflow("param", "set", "scale.gain", "3", cwd=tmp_path).returncode == 0
        restarted = handflow("param", "set", "sink.log_every", "25", "--restart", cwd=tmp_path)
        assert restarted.returncode == 0, restarted.stderr
        time.sleep(0.5)
    finally:
        run.send_signal(signal.SIGINT)
        _, err = run.communicate(timeout=60)
    assert run.returncode == 0, err
    replay = handflow(
        "replay", "live.mcap", "--into", str(write_graph(tmp_path / "r.yaml", unique("replay"), REPLAY_TARGET)),
        "--lockstep", "--record", "replayed.mcap", cwd=tmp_path,
    )  # fmt: skip
    assert replay.returncode == 0 and "not applied: sink.log_every" in replay.stderr, replay.stderr
    code, out, _ = _compare(tmp_path / "live.mcap", tmp_path / "replayed.mcap", "--json")
    assert code == 0, out
    assert sorted(t["topic"] for t in out["topics"]) == ["scale/out", "source/out"]
    code, table, _ = _compare(tmp_path / "live.mcap", tmp_path / "replayed.mcap", "--topics", "_runtime/*")
    assert code == 1 and "_runtime/events" in table  # the restart: only in the live run
