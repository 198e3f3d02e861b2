"""Live view: a graph run with --foxglove advertises its topics to a real Foxglove WebSocket client."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from handflow.framework.network.sessions import free_tcp_port
from tests.foxglove_client import connect_foxglove

pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]


def advertised_topics(port: int, graph: str, timeout: float = 20.0) -> set[str]:
    """Topics a real Foxglove WebSocket client sees advertised, once the graph's source and sink showed up."""
    deadline = time.time() + timeout
    ws = connect_foxglove(port, timeout)
    topics: set[str] = set()
    with ws:
        while (
            time.time() < deadline
            and not {f"/handflow/{graph}/source/out", f"/handflow/{graph}/sink/_health"} <= topics
        ):
            try:
                frame = ws.recv(timeout=1)
            except TimeoutError:
                continue
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg.get("op") == "advertise":
                    topics |= {c["topic"] for c in msg["channels"]}
    return topics


def test_run_with_foxglove_streams_topics(tmp_path):
    graph = tmp_path / "g.yaml"
    graph.write_text(
        "name: fx\nnodes:\n  - id: source\n    plugin: basic.signal\n    params: {rate_hz: 20}\n"
        "  - id: sink\n    plugin: basic.sink\n    inputs: {in: source/out}\n"
    )
    port = free_tcp_port()
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "handflow.framework.cli",
            "run",
            str(graph),
            "--duration",
            "12",
            "--foxglove",
            str(port),
        ],
        cwd=REPO,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        topics = advertised_topics(port, "fx")
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=30)
    assert {"/handflow/fx/source/out", "/handflow/fx/sink/_health"} <= topics, err
    assert proc.returncode == 0


def test_port_in_use_is_a_clear_error(tmp_path, run_handflow):
    graph = tmp_path / "g.yaml"
    graph.write_text("name: fx2\nnodes:\n  - id: source\n    plugin: basic.signal\n    params: {rate_hz: 5}\n")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        proc = run_handflow("run", str(graph), "--duration", "2", "--foxglove", str(s.getsockname()[1]))
    assert proc.returncode == 2
    assert "in use" in proc.stderr and "--foxglove PORT" in proc.stderr


def test_monitor_foxglove_joins_a_running_graph(tmp_path):
    graph = tmp_path / "g.yaml"
    graph.write_text(
        "name: fxm\nnodes:\n  - id: source\n    plugin: basic.signal\n    params: {rate_hz: 20}\n"
        "  - id: sink\n    plugin: basic.sink\n    inputs: {in: source/out}\n"
    )
    env = dict(__import__("os").environ, HANDFLOW_RUN_DIR=str(tmp_path / "runs"))
    run = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(graph), "--duration", "20"],
        cwd=REPO,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    port = free_tcp_port()
    time.sleep(2)
    mon = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "handflow.framework.cli",
            "monitor",
            "--graph",
            "fxm",
            "--once",
            "--listen",
            "12",
            "--foxglove",
            str(port),
        ],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        topics = advertised_topics(port, "fxm")
    finally:
        mon.terminate()
        run.terminate()
        mon.wait(timeout=30)
        run.wait(timeout=30)
    assert {"/handflow/fxm/source/out", "/handflow/fxm/sink/_health"} <= topics


def test_without_the_foxglove_extra_the_live_view_says_what_to_install(monkeypatch):
    from handflow.framework.observe import foxglove_bridge

    monkeypatch.setattr(foxglove_bridge, "foxglove", None)
    with pytest.raises(foxglove_bridge.BridgeError, match=r"pip install 'handflow\[foxglove\]'"):
        foxglove_bridge.start_bridge(None, "g", "127.0.0.1", 0)
