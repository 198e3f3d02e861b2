"""A remote host that disappears and returns: the graph reconnects by itself (docs/reliability.md).

Two launchers share one graph over TCP on this machine, as two hosts would: ``b`` (scale, sink)
and ``a`` (the source), one listening and the other connecting (both ways are tested). ``a`` is stopped for a few seconds and started again;
the sink on ``b`` receives again without anyone touching ``b``, and ``monitor`` run against ``b``
during the outage shows the source as missing.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest

from handflow.framework.network.sessions import free_tcp_port
from tests.framework.test_runtime_e2e import REPO, chain_graph, read_sink, start

pytestmark = pytest.mark.slow


def _rows_after(path, t_ns: int) -> int:
    return sum(1 for r in read_sink(path) if r["arrival_ns"] > t_ns)


def _wait_rows(path, t_ns: int, n: int, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if _rows_after(path, t_ns) >= n:
            return True
        time.sleep(0.2)
    return False


def _monitor_nodes(graph: str, port: int | None) -> set[str]:
    """Ids of the nodes ``monitor --once`` sees alive (through ``port``, else the local launchers' hubs)."""
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "handflow.framework.cli",
            "monitor",
            "--graph",
            graph,
            *(["--connect", f"tcp/127.0.0.1:{port}"] if port else []),
            "--once",
            "--json",
            "--listen",
            "2",
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 0, out.stderr
    return {n["id"] for n in json.loads(out.stdout)["nodes"] if n["alive"]}


@pytest.mark.parametrize("returning", ["connecting", "listening"])
def test_the_graph_reconnects_when_a_remote_host_returns_and_monitor_shows_the_outage(tmp_path, returning):
    """``returning``: whether the host that goes away and returns is the one that connects or listens."""
    port = free_tcp_port()
    listen = f"zenoh:\n  listen: [tcp/127.0.0.1:{port}]\n  connect: []"
    connect = f"zenoh:\n  listen: []\n  connect: [tcp/127.0.0.1:{port}]"
    zenoh_a, zenoh_b = (connect, listen) if returning == "connecting" else (listen, connect)
    graph_b = chain_graph(tmp_path, zenoh=zenoh_b, hosts=("a", "b", "b"))
    name = graph_b.read_text().split("\n", 1)[0].removeprefix("name: ")
    graph_a = tmp_path / "graph_a.yaml"
    graph_a.write_text(graph_b.read_text().replace(zenoh_b, zenoh_a))
    via = port if returning == "connecting" else None  # monitor reaches b through its listening port, if any
    sink = tmp_path / "sink.jsonl"
    b = start("run", str(graph_b), "--host", "b", "--duration", "60")
    a = start("run", str(graph_a), "--host", "a")
    try:
        assert _wait_rows(sink, 0, 50, 60), "no data from host a before the outage"
        assert "source" in _monitor_nodes(name, via)
        a.send_signal(signal.SIGINT)  # host a goes away
        a.communicate(timeout=30)
        outage_start = time.time_ns()
        time.sleep(1.0)
        nodes_during = _monitor_nodes(name, via)
        assert "source" not in nodes_during and {"scale", "sink"} <= nodes_during
        assert _rows_after(sink, outage_start + 500_000_000) == 0  # nothing arrives while a is gone
        back = time.time_ns()
        a = start("run", str(graph_a), "--host", "a")  # host a returns
        assert _wait_rows(sink, back, 50, 60), "the graph did not reconnect after host a returned"
        assert "source" in _monitor_nodes(name, via)
    finally:
        for p in (a, b):
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in (a, b):
            try:
                p.communicate(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
