"""Replay: argument checks, key remapping, timed replay into a sink, lock-step determinism under load."""

from __future__ import annotations

import argparse
import re
import signal
import subprocess
import sys
import threading

import numpy as np
import pytest

from handflow.framework.commands import replay as replay_cmd
from handflow.framework.files.mcap_writer import McapWriter
from handflow.framework.graphs.model import load_graph
from handflow.framework.messages import Array, Header
from handflow.framework.recorder.replay import external_inputs, remap_key
from tests.framework._rec_helpers import ended_within, handflow, read_jsonl, unique, wait_until, write_graph

T0 = 1_700_000_000_000_000_000
N = 60


@pytest.fixture(autouse=True)
def private_run_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))


@pytest.fixture
def recording(tmp_path):
    """60 messages of a recorded graph 'field', 100 Hz, plus a topic no target reads."""
    path = tmp_path / "field.mcap"
    rng = np.random.default_rng(7)
    with McapWriter(path) as w:
        for i in range(N):
            t = T0 + i * 10_000_000
            msg = Array(data=rng.normal(size=3))
            msg.header = Header("source", i + 1, t)
            w.write("handflow/field/source/out", msg, log_time_ns=t + 1000)
            other = Array(data=[float(i)])
            other.header = Header("other", i + 1, t)
            w.write("handflow/field/other/out", other, log_time_ns=t + 2000)
    return path


def _args(**kw) -> argparse.Namespace:
    base = dict(
        file="x.mcap",
        speed=1.0,
        loop=False,
        topics=None,
        into=None,
        lockstep=False,
        graph=None,
        connect=None,
        ready_timeout=30.0,
        step_timeout=10.0,
        record=None,
        certs=None,
        cert_name=None,
        credentials=None,
        user=None,
        foxglove=None,
        no_param_changes=False,
    )
    return argparse.Namespace(**{**base, **kw})


@pytest.mark.parametrize(
    "kw, message",
    [
        ({"speed": 0.0}, "--speed must be > 0"),
        ({"lockstep": True}, "--lockstep needs --into"),
        ({"record": "out.mcap"}, "--record needs --into"),
        ({"file": "/nonexistent/x.mcap"}, "not found"),
        ({"foxglove": 8765, "loop": True}, "leave out --loop"),
    ],
)
def test_bad_arguments_exit_2_with_what_to_change(kw, message, recording, capsys):
    kw.setdefault("file", str(recording))
    assert replay_cmd.run(_args(**kw)) == 2
    assert message in capsys.readouterr().err


def test_replay_without_a_running_graph_says_how_to_target_one(recording, capsys):
    assert replay_cmd.run(_args(file=str(recording))) == 2
    assert "no running graph 'field'" in capsys.readouterr().err


def test_remap_and_external_inputs(tmp_path):
    assert remap_key("handflow/field/glove/frames", "seg") == "handflow/seg/glove/frames"
    assert remap_key("handflow/field/glove/frames", None) == "handflow/field/glove/frames"
    graph = load_graph(
        write_graph(
            tmp_path / "g.yaml",
            "g",
            """external: {glove/frames: Array}
nodes:
  - {id: a, plugin: basic.transform, inputs: {in: glove/frames}}
  - {id: b, plugin: basic.sink, inputs: {in: a/out}}
""",
        )
    )
    assert external_inputs(graph) == {"glove/frames"}


def _into_graph(tmp_path, with_ticker: bool = False):
    ticker = (
        """  - id: ticker
    plugin: basic.signal
    params: {kind: sine, rate_hz: 50, width: 2}
  - id: ticks
    plugin: basic.sink
    params: {jsonl: ticks.jsonl}
    inputs: {in: ticker/out}
"""
        if with_ticker
        else ""
    )
    return write_graph(
        tmp_path / "into.yaml",
        unique("into"),
        f"""external: {{source/out: Array}}
nodes:
  - id: raw
    plugin: basic.sink
    params: {{jsonl: raw.jsonl}}
    inputs: {{in: source/out}}
  - id: scale
    plugin: basic.transform
    params: {{gain: 3.0, offset: 1.0}}
    inputs: {{in: source/out}}
  - id: scaled
    plugin: basic.sink
    params: {{jsonl: scaled.jsonl}}
    inputs: {{in: scale/out}}
{ticker}""",
    )


def _recorded_values(recording):
    from handflow.framework.files.mcap_reader import read_messages

    return [m for t, m, _ in read_messages(recording, ["source/out"])]


@pytest.mark.slow
def test_replay_into_a_sink_reproduces_the_recorded_values(tmp_path, recording):
    graph = _into_graph(tmp_path)
    proc = handflow("replay", str(recording), "--into", str(graph), "--speed", "2", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert f"replayed {N} message(s) on 1 topic(s)" in proc.stdout  # 'other/out' is not an input of the graph
    recorded = _recorded_values(recording)
    raw = read_jsonl(tmp_path / "raw.jsonl")
    assert [r["msg"]["data"] for r in raw] == [m.data.tolist() for m in recorded]
    assert [r["msg"]["header"] for r in raw] == [vars(m.header) for m in recorded]  # bytes published as recorded
    scaled = read_jsonl(tmp_path / "scaled.jsonl")
    np.testing.assert_allclose([r["msg"]["data"] for r in scaled], [3 * m.data + 1 for m in recorded])


def _lockstep_outputs(tmp_path, recording, *extra: str) -> dict[str, list[dict]]:
    graph = _into_graph(tmp_path, with_ticker=True)
    for f in ("raw", "scaled", "ticks"):
        (tmp_path / f"{f}.jsonl").unlink(missing_ok=True)
    proc = handflow("replay", str(recording), "--into", str(graph), "--lockstep", *extra, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "(lock-step)" in proc.stdout
    return {f: [r["msg"] for r in read_jsonl(tmp_path / f"{f}.jsonl")] for f in ("raw", "scaled", "ticks")}


@pytest.mark.slow
def test_lockstep_replay_is_identical_whatever_the_load(tmp_path, recording):
    quiet = _lockstep_outputs(tmp_path, recording, "--record", str(tmp_path / "replayed.mcap"))
    burner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        loaded = _lockstep_outputs(tmp_path, recording)
    finally:
        burner.kill()
        burner.wait()
    assert loaded == quiet
    assert len(quiet["raw"]) == len(quiet["scaled"]) == N
    # the ticking source ran on virtual time: 50 Hz over the 590 ms the recording spans
    stamps = [m["header"]["stamp_ns"] for m in quiet["ticks"]]
    assert stamps == [T0 + k * 20_000_000 for k in range(1, 30)]
    assert [m["header"]["stamp_ns"] for m in quiet["scaled"]] == [T0 + i * 10_000_000 for i in range(N)]
    # --record kept the replayed graph's outputs: the same messages the sink wrote
    from handflow.framework.files.mcap_reader import read_messages

    recorded_scaled = [m.to_dict() for t, m, _ in read_messages(tmp_path / "replayed.mcap") if t.endswith("/scale/out")]
    assert recorded_scaled == quiet["scaled"]


def test_a_stop_before_the_graph_is_launched_exits_130(tmp_path, recording, capsys):
    stop = threading.Event()
    stop.set()  # Ctrl-C while the recording and the graph were read
    args = _args(file=str(recording), into=str(_into_graph(tmp_path)))
    assert replay_cmd._run(args, stop) == 130
    assert capsys.readouterr().err.strip() == "interrupted"
    assert not (tmp_path / "raw.jsonl").exists()  # nothing was launched


def _long_recording(path, seconds: float = 30.0):
    """``seconds`` of graph 'field''s source/out at 100 Hz: a replay still running when it is signalled."""
    with McapWriter(path) as w:
        for i in range(int(seconds * 100)):
            t = T0 + i * 10_000_000
            msg = Array(data=[float(i), 0.0, 1.0])
            msg.header = Header("source", i + 1, t)
            w.write("handflow/field/source/out", msg, log_time_ns=t)
    return path


@pytest.mark.slow
@pytest.mark.parametrize("moment", ["replaying", "starting"])
def test_a_signalled_replay_stops_in_order_and_says_what_it_replayed(tmp_path, moment):
    """``handflow replay --into`` takes SIGTERM (replaying) and Ctrl-C (while its graph starts) as a stop
    request (:class:`StopSignals`): it exits 0 within 10 s leaving no process, prints how much it replayed
    and its ``--record`` file opens with every message the graph's sink wrote."""
    from handflow.framework.files.mcap_reader import iter_recording

    take = _long_recording(tmp_path / "take.mcap")
    out = tmp_path / "replayed.mcap"
    with open(tmp_path / "stdout.txt", "w") as stdout_file:
        proc = subprocess.Popen(
            [sys.executable, "-m", "handflow.framework.cli", "replay", str(take)]
            + ["--into", str(_into_graph(tmp_path)), "--record", str(out)],
            cwd=tmp_path,
            text=True,
            stdout=stdout_file,
            stderr=subprocess.PIPE,
        )
    if moment == "replaying":
        wait_until(lambda: len(read_jsonl(tmp_path / "raw.jsonl")) >= 50, timeout=60, what="the sink's 50th message")
        err = ended_within(proc, 10, tmp_path, "replay", signal.SIGTERM)
    else:  # the launcher's run-file: its hub is open, its nodes are starting
        wait_until(lambda: list((tmp_path / "runs").glob("*.json")), timeout=60, what="the launcher's run-file")
        err = ended_within(proc, 10, tmp_path, "replay", signal.SIGINT)
    stdout = (tmp_path / "stdout.txt").read_text()
    assert proc.returncode == 0, err
    assert "Traceback" not in err
    replayed = re.fullmatch(
        r"replayed (\d+) message\(s\) on [01] topic\(s\) into graph '\w+' before it was stopped \(Ctrl-C or SIGTERM\)",
        stdout.strip(),
    )
    assert replayed, stdout
    n = int(replayed.group(1))
    assert (n >= 50) if moment == "replaying" else (n < 3000), n
    topics = [rm.topic for rm in iter_recording(out)]  # a complete MCAP
    assert topics.count(f"handflow/{load_graph(tmp_path / 'into.yaml').name}/source/out") == n
