"""End to end over real Zenoh sessions and real processes: run, supervise, stop, span two launchers."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from handflow.framework.network.sessions import free_tcp_port

pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]


def chain_graph(tmp_path: Path, rate: float = 100, extra_scale: str = "", zenoh: str = "", hosts=("", "", "")) -> Path:
    h = [f"\n    host: {x}" if x else "" for x in hosts]
    text = f"""name: chain_{tmp_path.name[-8:].replace("-", "_")}
{zenoh}
nodes:
  - id: source
    plugin: basic.signal
    params: {{kind: sine, rate_hz: {rate}, width: 4}}{h[0]}
  - id: scale
    plugin: basic.transform
    params: {{gain: 2.0, offset: 1.0}}
    inputs: {{in: source/out}}{h[1]}{extra_scale}
  - id: sink
    plugin: basic.sink
    params: {{jsonl: {tmp_path / "sink.jsonl"}}}
    inputs: {{in: scale/out}}{h[2]}
"""
    path = tmp_path / "graph.yaml"
    path.write_text(text)
    return path


def start(*args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", *args],
        cwd=REPO,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )


def read_sink(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def _wait_rows(path: Path, n: int, timeout: float = 60.0) -> None:
    """Until the sink has written ``n`` rows to ``path``: its graph is up and data flows through it."""
    deadline = time.monotonic() + timeout
    while len(read_sink(path)) < n:
        assert time.monotonic() < deadline, f"the sink wrote {len(read_sink(path))} of {n} rows"
        time.sleep(0.1)


def test_three_processes_pass_data_end_to_end(tmp_path):
    graph = chain_graph(tmp_path)
    proc = start("run", str(graph), "--duration", "3", "--summary-json", str(tmp_path / "summary.json"))
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    pids = set(re.findall(r"started \w+ \(pid (\d+)\)", err))
    assert len(pids) == 3  # one process per node
    rows = read_sink(tmp_path / "sink.jsonl")
    assert len(rows) > 100
    seqs = [r["msg"]["header"]["seq"] for r in rows]
    assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
    for row in rows[:20]:  # transform applied: (data - 1) / 2 is sin/cos of one phase, shifted by quarters
        v = (np.asarray(row["msg"]["data"]) - 1.0) / 2.0
        assert np.isclose(v[0] ** 2 + v[1] ** 2, 1.0) and np.allclose(v[2:], -v[:2])
    assert "received" in err  # the sink's teardown ran at the end of --duration
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert all(u["restarts"] == 0 for u in summary.values())


def test_kill_9_restarts_node_and_counts_gaps(tmp_path):
    graph = chain_graph(tmp_path, extra_scale="\n    restart: {policy: on-failure, max_restarts: 2, backoff_s: 0.5}")
    proc = start("run", str(graph), "--duration", "7", "--summary-json", str(tmp_path / "summary.json"))
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stderr), daemon=True)
    reader.start()
    deadline = time.time() + 20
    pid = None
    while time.time() < deadline and pid is None:
        m = [re.search(r"started scale \(pid (\d+)\)", ln) for ln in list(lines)]
        pid = next((int(x.group(1)) for x in m if x), None)
        time.sleep(0.1)
    assert pid, "".join(lines)
    _wait_rows(tmp_path / "sink.jsonl", 50)  # the graph runs before 'scale' is killed
    os.kill(pid, signal.SIGKILL)
    killed_at = time.time_ns()
    proc.wait(timeout=60)
    reader.join(timeout=5)
    log = "".join(lines)
    assert proc.returncode == 0, log
    assert "scale failed (killed by signal 9); restarting" in log
    rows = read_sink(tmp_path / "sink.jsonl")
    after = [r for r in rows if r["arrival_ns"] > killed_at]
    assert len(after) > 50, "the graph did not go on after the restart"
    seqs = [r["msg"]["header"]["seq"] for r in rows]
    assert seqs == sorted(seqs), "the restarted node must continue its sequence numbers"
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["scale"]["restarts"] == 1
    assert summary["scale"]["gaps"]["scale"] > 0  # messages the source sent while 'scale' was down


def test_sigint_stops_in_order(tmp_path):
    graph = chain_graph(tmp_path)
    proc = start("run", str(graph))
    _wait_rows(tmp_path / "sink.jsonl", 50)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert "received" in err  # teardown of the sink ran


def test_two_launchers_share_one_graph_over_tcp(tmp_path):
    port = free_tcp_port()
    zenoh_a = f"zenoh:\n  listen: [tcp/127.0.0.1:{port}]\n  connect: []"
    graph = chain_graph(tmp_path, zenoh=zenoh_a, hosts=("a", "b", "b"))
    text = graph.read_text()
    graph_b = tmp_path / "graph_b.yaml"
    graph_b.write_text(
        text.replace(f"listen: [tcp/127.0.0.1:{port}]\n  connect: []", f"listen: []\n  connect: [tcp/127.0.0.1:{port}]")
    )
    a = start("run", str(graph), "--host", "a", "--duration", "6")
    time.sleep(0.5)
    b = start("run", str(graph_b), "--host", "b", "--duration", "5")
    _, err_b = b.communicate(timeout=60)
    _, err_a = a.communicate(timeout=60)
    assert a.returncode == 0 and b.returncode == 0, err_a + err_b
    assert "started source" in err_a and "started source" not in err_b
    rows = read_sink(tmp_path / "sink.jsonl")
    assert len(rows) > 100  # source on launcher a reached scale and sink on launcher b


def test_a_node_that_keeps_failing_is_a_crash_loop_with_its_log_and_exit_code_3(tmp_path):
    graph = chain_graph(tmp_path)  # crashes at its first tick: one name in the CSV header, two values a row
    (tmp_path / "wide.csv").write_text("a\n1,2\n3,4\n")
    graph.write_text(
        graph.read_text().replace(
            "params: {kind: sine, rate_hz: 100, width: 4}",
            "params: {kind: csv, csv: wide.csv, rate_hz: 100}\n    restart: {max_restarts: 2, backoff_s: 0.1}",
        )
    )
    proc = start("run", str(graph), "--duration", "4")
    _, err = proc.communicate(timeout=90)
    assert proc.returncode == 3, err
    assert "crash loop: source failed 3 times" in err
    assert "names for 2 values" in err.split("crash loop:")[1]  # the node's own log lines are in the report


def _running(pid: int) -> bool:
    """Whether a process exists and is not a zombie (an exited child nobody reaped yet)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


def _descendants(pid: int) -> list[int]:
    found = []
    for child in subprocess.run(["pgrep", "-P", str(pid)], capture_output=True, text=True).stdout.split():
        found += [int(child), *_descendants(int(child))]
    return found


def test_no_node_outlives_a_killed_launcher(tmp_path):
    graph = chain_graph(tmp_path)
    proc = start("run", str(graph))
    try:
        deadline = time.monotonic() + 60
        while not read_sink(tmp_path / "sink.jsonl") and time.monotonic() < deadline:
            time.sleep(0.2)
        children = _descendants(proc.pid)
        assert len(children) == 4  # the zygote and the three node processes it forked
    finally:
        proc.kill()  # SIGKILL: no chance to stop the nodes itself
        proc.wait()
    deadline = time.monotonic() + 15  # the watchdog polls every 0.2 s and gives 1.5 s to stop in order
    while (alive := [pid for pid in children if _running(pid)]) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not alive, f"node processes {alive} outlived the launcher"
