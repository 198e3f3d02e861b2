"""Garbage from an outside Zenoh peer onto every input of the flagship: every node stays alive (docs/robustness.md).

The graph runs with ``transport: {local: zenoh}``: over the default local transport (iceoryx2) a
node reads its same-host inputs from shared memory only, so an outside Zenoh peer cannot reach
them at all (docs/shared_memory.md); the frames of that path are property-tested in
tests/framework/test_local_transport.py."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest
import yaml

from handflow.framework.files.mcap_reader import read_messages
from handflow.framework.messages import RuntimeEvent
from handflow.framework.runtime.discovery import join, live_runs
from tests.conftest import REPO
from tests.garbage import GarbagePeer

pytestmark = pytest.mark.slow


def _wait(pred, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not pred():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.2)


def _with_absolute_paths(value, base):
    """``value`` (a graph file's params) with every string naming a file under ``base`` made absolute."""
    if isinstance(value, dict):
        return {k: _with_absolute_paths(v, base) for k, v in value.items()}
    if isinstance(value, list):
        return [_with_absolute_paths(v, base) for v in value]
    return str(base / value) if isinstance(value, str) and (base / value).exists() else value


def test_every_node_survives_garbage_on_every_input(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    spec = yaml.safe_load((REPO / "configs/demo.yaml").read_text())
    spec["nodes"] = [
        {**n, "params": _with_absolute_paths(n.get("params") or {}, REPO / "configs")} for n in spec["nodes"]
    ]
    spec["transport"] = {"local": "zenoh"}
    spec.pop("record", None)
    graph_file = tmp_path / "demo.yaml"
    graph_file.write_text(yaml.safe_dump(spec))
    graph = spec["name"]
    inputs = sorted({f"handflow/{graph}/{src}" for n in spec["nodes"] for src in (n.get("inputs") or {}).values()})
    node_ids = [n["id"] for n in spec["nodes"]]
    rec = tmp_path / "demo.mcap"
    proc = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(graph_file), "--record", str(rec)],
        cwd=REPO,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        _wait(lambda: live_runs() or proc.poll() is not None, 60, "the run-file")
        session, _ = join(graph)
        peer = GarbagePeer(session, graph, inputs)
        _wait(lambda: peer.ready(len(node_ids)) or proc.poll() is not None, 120, "all nodes up and real payloads")
        assert proc.poll() is None
        before = peer.nodes()
        sent = peer.publish(per_topic=400, seed=3)
        time.sleep(3.0)  # heartbeats and drop reports of the garbage arrive
        # on a saturated machine a process still working through the garbage sends its heartbeat late
        _wait(lambda: all(n["alive"] for n in peer.nodes().values()), 30, "a heartbeat of every node after the garbage")
        after = peer.nodes()
        peer.close()
        session.close()
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=90)
    assert sent == 400 * len(inputs)
    assert proc.returncode == 0, err[-3000:]
    assert "Traceback" not in err and "failed in on_message" not in err, err[-3000:]
    for nid in node_ids:
        assert after[nid]["alive"] and after[nid]["pid"] == before[nid]["pid"], (nid, after[nid])
        assert after[nid]["restarts_seen"] == 0
    consumers = {n["id"] for n in spec["nodes"] if n.get("inputs")}
    for nid in consumers:
        assert after[nid]["dropped"] > before[nid]["dropped"], (nid, after[nid])
        assert after[nid]["handled"] > before[nid]["handled"]  # real traffic still flows
    events = [msg for topic, msg, _ in read_messages(rec) if topic == f"handflow/{graph}/_runtime/events"]
    dropped = [e for e in events if isinstance(e, RuntimeEvent) and e.kind == "dropped"]
    assert {e.topic for e in dropped} == set(inputs)
    assert sum(e.count for e in dropped) >= len(inputs) * 100
