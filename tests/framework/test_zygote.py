"""The fork server that starts node processes (docs/architecture.md, "Process start-up"): a forked
child runs the node runtime in the launcher's directory and environment, its stderr reaches the
launcher, its exit status (a signal as a negative code) is reported, and the zygote ends with the
launcher's end of the socket."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from handflow.framework.graphs.model import load_graph
from handflow.framework.runtime.launcher import run_graph
from handflow.framework.runtime.zygote import Zygote
from tests.framework.test_runtime_e2e import chain_graph, read_sink

SINK_GRAPH = """name: zygote_probe
external: {{nobody/out: JointState}}
nodes:
  - id: sink
    plugin: basic.sink
    params: {{jsonl: {out}}}
    inputs: {{in: nobody/out}}
"""


def _title(pid: int) -> str:
    return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()


def _running(pid: int) -> bool:
    """Whether a process exists and is not a zombie (an exited child nobody reaped yet)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.fixture
def zygote(tmp_path, monkeypatch):
    graph = tmp_path / "graph.yaml"
    graph.write_text(SINK_GRAPH.format(out=tmp_path / "sink.jsonl"))
    z = Zygote.start(graph)
    yield z
    z.close()


def test_a_failing_child_reports_its_exit_code_and_stderr(zygote, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a relative graph path resolves against the launcher's directory
    (tmp_path / "broken.yaml").write_text("name: [unclosed\n")
    proc = zygote.spawn(["broken.yaml", "--nodes", "sink", "--hub", "tcp/127.0.0.1:9"])
    assert proc is not None
    assert proc.wait(timeout=60) == 1
    err = proc.stderr.read()
    assert "broken.yaml" in err, err


def test_a_killed_child_reports_the_signal_and_shows_its_command(zygote, tmp_path):
    proc = zygote.spawn([str(tmp_path / "graph.yaml"), "--nodes", "sink", "--hub", "tcp/127.0.0.1:9"])
    assert proc.poll() is None
    deadline = time.monotonic() + 15  # the child names itself first thing
    while "--nodes sink" not in _title(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert "-m handflow.framework.runtime.runner" in _title(proc.pid) and "--nodes sink" in _title(proc.pid)
    proc.send_signal(signal.SIGKILL)
    assert proc.wait(timeout=30) == -signal.SIGKILL
    proc.send_signal(signal.SIGTERM)  # a process that has exited is not signalled again


def test_the_zygote_ends_with_the_launchers_socket(zygote, tmp_path):
    proc = zygote.spawn([str(tmp_path / "graph.yaml"), "--nodes", "sink", "--hub", "tcp/127.0.0.1:9"])
    zygote.close()
    assert zygote.proc.returncode == 0
    assert zygote.spawn(["x"]) is None  # the launcher then starts node processes afresh
    deadline = time.monotonic() + 15  # the orphaned child sees its parent gone and stops
    while _running(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _running(proc.pid)


@pytest.mark.slow
def test_without_the_zygote_node_processes_are_fresh_interpreters(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_ZYGOTE", "0")
    launcher = run_graph(load_graph(chain_graph(tmp_path)), duration_s=1.0)
    launcher.close()
    assert launcher.zygote is None
    assert read_sink(tmp_path / "sink.jsonl")
    assert all(u["exit_codes"] == [0] for u in launcher.summary().values())


@pytest.mark.slow
def test_a_killed_zygote_costs_a_restart_not_the_graph(tmp_path):
    """kill -9 of the zygote: its node processes see their parent gone and stop; the launcher restarts
    them as fresh interpreters and data flows again."""
    graph = chain_graph(tmp_path)
    summary = tmp_path / "summary.json"
    proc = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(graph), "--summary-json", str(summary)],
        cwd=tmp_path,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 60
        while not read_sink(tmp_path / "sink.jsonl") and time.monotonic() < deadline:
            time.sleep(0.2)
        children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()
        (zygote_pid,) = [int(p) for p in children if "handflow.framework.runtime.zygote" in _title(int(p))]
        subprocess.run(["kill", "-9", str(zygote_pid)], check=True)
        killed_at = time.time_ns()
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if len([r for r in read_sink(tmp_path / "sink.jsonl") if r["arrival_ns"] > killed_at + 1e9]) > 50:
                break
            time.sleep(0.2)
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err[-3000:]
    assert "starting it as a new interpreter" in err
    after = [r for r in read_sink(tmp_path / "sink.jsonl") if r["arrival_ns"] > killed_at + 1e9]
    assert len(after) > 50, "no data after the node processes were restarted"
    assert all(unit["restarts"] == 1 for unit in json.loads(summary.read_text()).values()), err[-3000:]
