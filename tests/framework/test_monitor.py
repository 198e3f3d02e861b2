"""Monitor: gap and restart counting over real Zenoh sessions, and `monitor --once --json` on a live graph."""

from __future__ import annotations

import io
import json
import re
import signal
import time

import numpy as np
import pytest

from handflow.framework.messages import Array, Header, RuntimeEvent, Status, encode
from handflow.framework.network import sessions as transport
from handflow.framework.network.settings import ZenohSettings
from handflow.framework.observe.monitor import Monitor, render, summarize
from handflow.framework.recorder.replay import wait_matching
from tests.framework._rec_helpers import chain, handflow, start, unique, wait_counted, wait_until


@pytest.fixture(autouse=True)
def private_run_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))


@pytest.fixture
def sessions():
    hub_ep = transport.hub_endpoint_for()
    hub = transport.open_hub(ZenohSettings(), hub_ep)
    peer = transport.open_node_session(ZenohSettings(), hub_ep)
    yield hub, peer
    peer.close()
    hub.close()


def _array(seq: int, stamp: int) -> bytes:
    msg = Array(data=np.array([seq, 2.0 * seq]))
    msg.header = Header("src", seq, stamp)
    return encode(msg)


def _status(pid: int) -> bytes:
    msg = Status(counters={"dropped.in": 1, "gaps.in": 3, "handled.in": 10, "published.out": 9}, text=f"pid {pid}")
    msg.header = Header("node", 0, time.time_ns())
    return encode(msg)


def test_gaps_restarts_latency_and_health_from_real_zenoh_traffic(sessions):
    hub, peer = sessions
    mon = Monitor(peer, "g")
    data = hub.declare_publisher("handflow/g/src/out")
    health = hub.declare_publisher("handflow/g/node/_health")
    assert wait_matching([data, health], 10)
    for seq in (1, 2, 3, 7, 8, 2, 3):  # 3 lost after 3; the drop back to 2 is a replay loop, not a gap
        data.put(_array(seq, time.time_ns() - 5_000_000))
        time.sleep(0.005)
    health.put(_status(100))
    health.put(_status(100))
    health.put(_status(101))  # a new pid: the node was restarted
    wait_until(
        lambda: (
            mon.nodes.get(("g", "node"))
            and mon.nodes["g", "node"].restarts == 1
            and getattr(mon.topics.get("handflow/g/src/out"), "count", 0) == 7
        ),
        10,
        "all samples and the three heartbeats",
    )
    snap = mon.snapshot()
    (topic,) = snap["topics"]
    assert topic["topic"] == "handflow/g/src/out" and topic["gaps"] == 3 and topic["count"] == 7
    assert topic["latency_ms"] >= 5.0 and topic["rate_hz"] > 0
    assert topic["last"] == "[3, 6] (2)"
    (node,) = snap["nodes"]
    assert node["id"] == "node" and node["alive"] and node["restarts_seen"] == 1
    assert (node["dropped"], node["input_gaps"], node["handled"], node["published"]) == (1, 3, 10, 9)
    mon.close()


def test_dropped_events_count_on_the_topic_they_arrived_on(sessions):
    hub, peer = sessions
    mon = Monitor(peer, "g")
    events = hub.declare_publisher("handflow/g/_runtime/events")
    assert wait_matching([events], 10)
    for count in (4, 2):
        event = RuntimeEvent(kind="dropped", node="human", topic="handflow/g/glove/frames", count=count, detail="bad")
        event.header = Header("human", 0, time.time_ns())
        events.put(encode(event))
    events.put(b"\xff garbage")  # the monitor itself survives garbage
    wait_until(
        lambda: mon.topics.get("handflow/g/glove/frames", None) and mon.topics["handflow/g/glove/frames"].dropped == 6,
        10,
        "events",
    )
    rows = {t["topic"]: t for t in mon.snapshot()["topics"]}
    assert rows["handflow/g/glove/frames"]["dropped"] == 6 and rows["handflow/g/glove/frames"]["count"] == 0
    mon.close()


def test_summarize_payloads():
    msg = Status(state="warn", text="low battery")
    assert summarize(msg) == "warn low battery"
    assert summarize(Array(data=np.arange(10.0))) == "[0, 1, 2, 3, …] (10)"


def test_json_without_once_is_rejected():
    proc = handflow("monitor", "--json")
    assert proc.returncode == 2 and "--json needs --once" in proc.stderr


def _demo_like_snapshot() -> dict:
    """20 topics with long last values and 10 nodes, as the flagship shows them."""
    topics = [
        {
            "topic": f"handflow/demo/node{i}/port_{i}",
            "type": "handflow.JointState",
            "rate_hz": 50.0,
            "latency_ms": 1.25,
            "gaps": i % 2,
            "dropped": 0,
            "count": 1000 + i,
            "shm": i == 3,
            "path": "iceoryx2+zenoh" if i % 2 else "zenoh",
            "last": "names=[24] positions=[0.0741, 0.0133, -0.305, 0.977, …] (24) velocities=[0] hand='shadow'",
        }
        for i in range(20)
    ]
    nodes = [
        {"id": f"node{i}", "graph": "demo", "alive": i != 4, "last_heartbeat_s": 3.0, "pid": 40000 + i}
        | {"restarts_seen": 0, "dropped": 0, "input_gaps": 0, "handled": 123456, "published": 123456}
        for i in range(10)
    ]
    return {"topics": topics, "nodes": nodes}


def _printed(width: int | None) -> list[str]:
    from rich.console import Console

    console = Console(file=io.StringIO(), width=width or 1000, color_system=None)
    console.print(render(_demo_like_snapshot(), "handflow monitor — graph 'demo'", "demo", width))
    return console.file.getvalue().splitlines()


@pytest.mark.parametrize("width", [80, 160])
def test_the_table_fits_the_terminal_one_line_per_topic_and_node(width):
    """docs/monitoring.md, "Terminal width": columns are abbreviated or dropped, never wrapped."""
    lines = _printed(width)
    assert max(len(line) for line in lines) <= width
    assert len(lines) == (3 + 20) + (3 + 10), "\n".join(lines)  # title, header and rule per table, one line a row
    rows = [line for line in lines if line.startswith("node") and "/port_" in line]
    assert len(rows) == 20 and all(re.search(r"\b50\.0\b.*\b1\.25\b", row) for row in rows)  # rate and latency kept


def test_wide_shows_every_column_in_full():
    lines = _printed(None)
    assert len(lines) == (3 + 20) + (3 + 10)
    header = lines[1]
    for col in ("type", "rate Hz", "latency ms", "gaps/dropped", "count", "shm", "path", "last value"):
        assert col in header, header
    assert "hand='shadow'" in lines[3]  # the last value uncut


@pytest.mark.slow
def test_monitor_once_json_on_a_running_graph(tmp_path, monkeypatch):
    name = unique("mon")
    graph = chain(tmp_path / "g.yaml", name, rate=50)
    proc = start("run", str(graph))
    try:
        from handflow.framework.runtime.discovery import join, live_runs

        wait_until(lambda: any(r.graph == name for r in live_runs()), what="the run-file")
        session = join(name)[0]
        try:  # nodes up and publishing: the sink has handled a message
            wait_counted(session, name, {"sink": "handled.in"})
        finally:
            session.close()
        mon = handflow("monitor", "--graph", name, "--once", "--json", "--listen", "2")
        assert mon.returncode == 0, mon.stderr
        snap = json.loads(mon.stdout)
        monkeypatch.setenv("COLUMNS", "80")  # piped: the width comes from COLUMNS
        text = handflow("monitor", "--once", "--listen", "1")  # the only running graph is found by itself
    finally:
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=60)
    topics = {t["topic"]: t for t in snap["topics"]}
    assert set(topics) == {f"handflow/{name}/source/out", f"handflow/{name}/scale/out"}
    for t in topics.values():
        assert {"topic", "rate_hz", "latency_ms", "gaps"} <= set(t)
        assert t["rate_hz"] == pytest.approx(50, rel=0.3) and t["gaps"] == 0 and t["latency_ms"] is not None
        assert t["path"] == "iceoryx2+zenoh"  # to the next node in place, to the monitor over Zenoh
    assert sorted((n["id"], n["alive"]) for n in snap["nodes"]) == [("scale", True), ("sink", True), ("source", True)]
    assert text.returncode == 0 and "source/out" in text.stdout and "sink" in text.stdout
    lines = text.stdout.splitlines()
    assert max(len(line) for line in lines) <= 80 and len(lines) == (3 + 2) + (3 + 3), text.stdout
