"""Recording real graphs: SIGINT during `handflow run --record`, and `handflow record` from outside."""

from __future__ import annotations

import json
import os
import random
import re
import signal
import time

import pytest

from handflow.framework.files.mcap_reader import read_messages, read_report
from handflow.framework.runtime.discovery import live_runs
from tests.framework._rec_helpers import chain, ended_within, handflow, start, unique, wait_until

pytestmark = pytest.mark.slow


@pytest.fixture(autouse=True)
def private_run_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))


def _recorded(path) -> int:
    return read_report(path).messages if path.exists() else 0


def _before_the_handlers(proc, err: str) -> bool:
    """Whether the signal came before the command installed its handlers: killed by it, or a SIGINT in the
    interpreter's own start-up, which CPython ends with exit code 1 (docs/reliability.md)."""
    in_interpreter_start_up = (
        bool(re.search(r"^Fatal Python error: init_\w+:", err, re.M)) and "KeyboardInterrupt" in err
    )
    return proc.returncode < 0 or (proc.returncode == 1 and in_interpreter_start_up)


def test_sigint_during_recording_leaves_a_complete_mcap(tmp_path):
    graph = chain(tmp_path / "g.yaml", unique("recint"))
    out = tmp_path / "run.mcap"
    proc = start("run", str(graph), "--record", str(out))
    try:
        wait_until(lambda: _recorded(out) >= 40, what="the first flushed chunks")  # readable while being written
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    report = read_report(out)
    assert report.complete and not report.error
    topics = {t.rsplit("/", 2)[-2] + "/" + t.rsplit("/", 1)[-1] for t in report.channels}
    assert topics == {"source/out", "scale/out"}  # data topics only, no _health
    assert report.messages >= 40
    assert report.metadata["handflow.graph"]["file"] == str(graph)
    assert json.loads(report.metadata["handflow.params"]["scale"]) == {"gain": 2.0, "offset": 0.0}


def test_record_command_joins_a_running_graph(tmp_path):
    name = unique("recout")
    graph = chain(tmp_path / "g.yaml", name)
    missing = handflow("record", name, "--out", str(tmp_path / "none.mcap"), "--duration", "1")
    assert missing.returncode == 2 and f"no running graph '{name}'" in missing.stderr

    proc = start("run", str(graph))
    try:
        wait_until(lambda: any(r.graph == name for r in live_runs()), what="the run-file")
        rec = handflow("record", name, "--out", str(tmp_path / "out.mcap"), "--duration", "2", "--topics", "source/*")
        assert rec.returncode == 0, rec.stderr
        assert "recorded" in rec.stdout
        assert (rec.stdout + rec.stderr).count("recorded ") == 1, rec.stderr  # the summary once, on stdout
    finally:
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=60)
    assert not live_runs()  # the launcher removed its run-file
    summary = json.loads(handflow("inspect", str(tmp_path / "out.mcap"), "--json").stdout)
    assert [t["topic"] for t in summary["topics"]] == [f"handflow/{name}/source/out"]
    assert summary["recovered"] is False and summary["topics"][0]["count"] >= 100
    assert summary["topics"][0]["rate_hz"] == pytest.approx(100, rel=0.25)
    assert "graph.yaml" in summary["attachments"]  # provenance found through the run-file


def test_duration_counts_from_every_node_ready(tmp_path):
    # start-up takes seconds; a one-second run still records about a second of a 100 Hz source
    graph = chain(tmp_path / "g.yaml", unique("recdur"))
    out = tmp_path / "short.mcap"
    res = handflow("run", str(graph), "--duration", "1", "--record", str(out))
    assert res.returncode == 0, res.stderr
    counts: dict[str, int] = {}
    for topic, _, _ in read_messages(out):
        counts[topic] = counts.get(topic, 0) + 1
    assert len(counts) == 2 and min(counts.values()) >= 50, counts


def test_a_recording_that_ends_empty_warns_and_fails(tmp_path):
    graph = chain(tmp_path / "g.yaml", unique("recnone"))
    graph.write_text(graph.read_text() + "record:\n  topics: [nobody/out]\n")
    out = tmp_path / "empty.mcap"
    res = handflow("run", str(graph), "--duration", "0.5", "--record", str(out))
    assert res.returncode == 1
    assert "holds no messages" in res.stderr and "record.topics" in res.stderr


def test_outputs_land_relative_to_the_current_directory_not_the_graph(tmp_path):
    graphs, work = tmp_path / "graphs", tmp_path / "work"
    graphs.mkdir()
    work.mkdir()
    graph = chain(graphs / "g.yaml", unique("reccwd"))
    text = graph.read_text().replace("plugin: basic.sink", "plugin: basic.sink\n    params: {jsonl: out/sink.jsonl}")
    graph.write_text(text + "record:\n  path: out/run.mcap\n")
    res = handflow("run", str(graph), "--duration", "1", cwd=work)
    assert res.returncode == 0, res.stderr
    assert (work / "out" / "run.mcap").is_file() and (work / "out" / "sink.jsonl").is_file()
    assert not (graphs / "out").exists()


def test_the_live_recording_keeps_every_message_published_before_the_stop(tmp_path):
    """A 500 Hz source into two transforms and a sink, stopped mid-stream: the launcher stops upstream first
    and drains, so every stage recorded exactly what the source published (its last heartbeat says how many)."""
    name = unique("recdrain")
    graph = chain(tmp_path / "g.yaml", name, rate=500)
    text = graph.read_text().replace(
        "inputs: {in: scale/out}", "inputs: {in: scale2/out}\n    params: {jsonl: sink.jsonl}"
    )
    text += "  - id: scale2\n    plugin: basic.transform\n    inputs: {in: scale/out}\n"
    graph.write_text(text + "record:\n  topics: ['**', 'source/_health']\n")
    out = tmp_path / "run.mcap"
    res = handflow("run", str(graph), "--duration", "1.5", "--record", str(out), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    recorded: dict[str, list] = {}
    for topic, msg, _ in read_messages(out, ["**", "source/_health"]):
        recorded.setdefault(topic.split("/", 2)[2], []).append(msg)
    last_health = recorded["source/_health"][-1]
    assert last_health.state == "stopped"
    published = int(last_health.counters["seq.out.out"])
    assert published > 300
    assert [m.header.seq for m in recorded["source/out"]] == list(range(1, published + 1))
    assert len(recorded["scale/out"]) == len(recorded["scale2/out"]) == published
    assert len((tmp_path / "sink.jsonl").read_text().splitlines()) == published


def test_a_shipped_graph_runs_by_name_from_anywhere(tmp_path):
    res = handflow("validate", "basic_chain", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    missing = handflow("validate", "no_such_graph", cwd=tmp_path)
    assert missing.returncode == 2 and "shipped graphs: " in missing.stderr and "demo" in missing.stderr


SIGNAL_MOMENTS = int(os.environ.get("HANDFLOW_SIGNAL_MOMENTS", "8"))
STOP_WITHIN_S = 10.0  # a signalled launcher has exited by then, its node processes and zygote with it


def test_sigint_and_sigterm_at_random_moments_always_leave_an_mcap_that_opens(tmp_path):
    """Seeded moments from start-up to steady recording, each ended within 10 s with no process left;
    docs/reliability.md runs 50."""
    rng = random.Random(0)
    graph = chain(tmp_path / "g.yaml", unique("recsig"))
    for i in range(SIGNAL_MOMENTS):
        out = tmp_path / f"run{i}.mcap"
        sig = (signal.SIGINT, signal.SIGTERM)[i % 2]
        proc = start("run", str(graph), "--record", str(out))
        time.sleep(rng.uniform(0.0, 6.0))
        before = _recorded(out)  # what the recorder had flushed when the signal came
        proc.send_signal(sig)
        err = ended_within(proc, STOP_WITHIN_S, tmp_path, f"moment {i} ({sig.name})")
        if _before_the_handlers(proc, err):  # nothing was recorded yet
            assert not out.exists(), f"moment {i} ({sig.name}): ended by the signal after the recording began"
            continue
        assert proc.returncode in (0, 1, 130), f"moment {i} ({sig.name}): exit {proc.returncode}\n{err[-2000:]}"
        if proc.returncode == 1:  # stopped before anything was recorded: said so
            assert "holds no messages" in err, err[-2000:]
        if out.exists():
            report = read_report(out)
            assert report.complete and not report.error, f"moment {i}: {report.describe()}"
            assert report.messages >= before
