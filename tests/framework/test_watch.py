"""``handflow run --watch`` end to end (docs/tuning.md, "Editing a running graph"): a plugin whose source
lives in a temporary folder is edited while a real graph runs, and so is the graph file; only the
nodes concerned restart, the source's topic keeps flowing, a broken edit keeps the running version."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from handflow.framework import keys, wire
from handflow.framework.graphs.model import load_graph
from handflow.framework.runtime.discovery import join, live_runs
from handflow.framework.runtime.launcher import run_graph
from handflow.framework.runtime.live_params import forget_edited_params, overrides_file, save_override
from handflow.framework.testkit.plugin_dist import register_plugins
from tests.framework._rec_helpers import unique

REPO = Path(__file__).resolve().parents[2]
RATE_HZ = 50
PLUGIN = """from handflow.framework.files.params import StrictModel
from handflow.framework.messages import Array
from handflow.framework.plugin import Node

SHIFT = 0.0


class ShiftParams(StrictModel):
    scale: float = 1.0


class Shift(Node):
    Params = ShiftParams
    inputs = {"in": Array}
    outputs = {"out": Array}

    def on_message(self, port, msg):
        out = Array(data=msg.data * self.params.scale + SHIFT, shape=list(msg.shape))
        self.ctx.publish("out", out, stamp_ns=msg.header.stamp_ns)
"""
GRAPH = f"""nodes:
  - id: source
    plugin: basic.signal
    params: {{rate_hz: {RATE_HZ}}}
  - id: shift
    plugin: temp.shift
    group: pair
    inputs: {{in: source/out}}
  - id: twin
    plugin: basic.transform
    group: pair
    inputs: {{in: source/out}}
  - id: sink
    plugin: basic.sink
    params: {{log_every: 0}}
    inputs: {{in: shift/out}}
"""
EXTRA = """  - id: extra
    plugin: temp.shift
    inputs: {in: source/out}
"""

pytestmark = pytest.mark.slow


class Topics:
    """Receive times and values of the graph's topics, and its runtime events, from a session of our own."""

    def __init__(self, graph: str) -> None:
        self.session, _ = join(graph)
        self.lock = threading.Lock()
        self.times: dict[str, list[float]] = {"source": [], "shift": [], "extra": []}
        self.values: dict[str, list[float]] = {"shift": [], "extra": []}
        self.headers: dict[str, list[tuple[int, float]]] = {node: [] for node in self.times}
        self.events: list = []
        self.subs = [
            self.session.declare_subscriber(keys.topic_key(graph, node, "out"), self._on(node)) for node in self.times
        ]
        self.subs.append(self.session.declare_subscriber(keys.topic_key(graph, "_runtime", "events"), self._on_event))

    def _on(self, node: str):
        def callback(sample) -> None:
            now, msg = time.monotonic(), wire.unpack(*wire.sample_parts(sample))
            with self.lock:
                self.times[node].append(now)
                self.headers[node].append((msg.header.seq, msg.header.stamp_ns / 1e9))
                if node in self.values:
                    self.values[node].append(float(msg.data[0]))

        return callback

    def _on_event(self, sample) -> None:
        event = wire.unpack(*wire.sample_parts(sample))
        with self.lock:
            self.events.append(event)

    def wait_for(self, node: str, predicate, timeout: float) -> float:
        """The receive time of the first output of ``node`` from now whose value satisfies ``predicate``."""
        with self.lock:
            start = len(self.values[node])
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                for t, v in zip(self.times[node][start:], self.values[node][start:]):
                    if predicate(v):
                        return t
            time.sleep(0.01)
        raise AssertionError(f"no such output of {node} within {timeout}s; last: {self.values[node][-3:]}")

    def reloads(self) -> list[str]:
        """The reload events so far, as ``verb node,node``, and forget them."""
        with self.lock:
            events, self.events = self.events, []
        return [f"{e.detail.split(':')[0]} {e.node}" for e in events if e.kind == "reload"]

    def largest_gap(self, node: str, since: float) -> float:
        """The longest pause of ``node/out`` since the wall-clock time ``since``, by the stamps of its messages
        (when the node published them, free of this test's own scheduling), after checking none was lost."""
        with self.lock:
            headers = [(seq, stamp) for seq, stamp in self.headers[node] if stamp >= since]
        assert [seq for seq, _ in headers] == list(range(headers[0][0], headers[-1][0] + 1)), "messages were lost"
        return max(b[1] - a[1] for a, b in zip(headers, headers[1:]))

    def close(self) -> None:
        for sub in self.subs:
            sub.undeclare()
        self.session.close()


WAIT_S = 30.0  # a reload checks the edit in a process of its own: seconds on a busy machine


def wait_until(predicate, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, what
        time.sleep(0.02)


@pytest.fixture
def watched(tmp_path, monkeypatch):
    """The graph running with --watch in tmp_path (its plugin temp.shift in tmp_path/tempshift.py)."""
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    (tmp_path / "tempshift.py").write_text(PLUGIN)
    env = register_plugins(tmp_path, "tempshift", {"temp.shift": "tempshift:Shift"})
    name = unique("watch")
    graph = tmp_path / "g.yaml"
    graph.write_text(f"name: {name}\n{GRAPH}")
    log = (tmp_path / "run.log").open("w+")
    run = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "run", "g.yaml", "--watch", "--duration", "60"],
        cwd=tmp_path,
        env=env,
        stderr=log,
        text=True,
    )
    wait_until(lambda: live_runs() or run.poll() is not None, 30, "the graph did not start")
    topics = Topics(name)
    try:
        topics.wait_for("shift", lambda v: True, 30)
        yield tmp_path, graph, topics, lambda: (tmp_path / "run.log").read_text()
    finally:
        topics.close()
        run.terminate()
        run.wait(timeout=60)
        log.close()


def test_edits_restart_only_the_nodes_they_concern(watched):
    folder, graph, topics, output = watched
    plugin = folder / "tempshift.py"

    # a plugin edit restarts its node (and the other node of its group); the source runs on
    # (how long it takes is measured by benchmarks/watch_reload.py)
    edited, edited_wall = time.monotonic(), time.time()
    plugin.write_text(PLUGIN.replace("SHIFT = 0.0", "SHIFT = 100.0"))
    took = topics.wait_for("shift", lambda v: v > 50, WAIT_S) - edited
    wait_until(lambda: "reloaded: restarted shift, twin (tempshift.py changed) in" in output(), WAIT_S, "no 'reloaded'")
    assert topics.reloads() == ["restarted shift,twin"]
    gap = topics.largest_gap("source", edited_wall)
    assert gap < 3 / RATE_HZ, f"source/out paused {gap * 1000:.0f} ms during the reload"
    print(f"plugin edit → new output in {took:.2f}s; largest gap on source/out {gap * RATE_HZ:.1f} periods")

    graph.write_text(graph.read_text() + EXTRA)  # a node added: started, fed as the others are
    topics.wait_for("extra", lambda v: v > 50, WAIT_S)
    assert topics.reloads() == ["started extra"]

    # a broken edit is refused with file:line, the running version keeps publishing
    plugin.write_text(PLUGIN.replace("SHIFT = 0.0", "SHIFT = 100.0\ndef broken(:"))
    wait_until(lambda: "not taken" in output(), WAIT_S, "the broken edit was not reported")
    for node_line in (7, 19):  # every node of the plugin, where the graph names it, and the plugin's line
        assert f"g.yaml:{node_line}: plugin 'temp.shift' (tempshift:Shift) failed to load: SyntaxError" in output()
    assert f"(at {plugin}:6)" in output()
    assert "the running nodes keep their version" in output()
    topics.wait_for("shift", lambda v: v > 50, WAIT_S)
    assert topics.reloads() == []

    # undone: back to the running version, said so, nothing restarted
    plugin.write_text(PLUGIN.replace("SHIFT = 0.0", "SHIFT = 100.0"))
    wait_until(lambda: "tempshift.py back to the running version: nothing to reload" in output(), 5, "not said")
    assert topics.reloads() == []

    # fixed: every node of the plugin restarts
    plugin.write_text(PLUGIN.replace("SHIFT = 0.0", "SHIFT = 200.0"))
    topics.wait_for("shift", lambda v: v > 150, WAIT_S)
    topics.wait_for("extra", lambda v: v > 150, WAIT_S)
    wait_until(lambda: "reloaded: restarted shift, twin; restarted extra" in output(), WAIT_S, "no 'reloaded'")
    assert sorted(topics.reloads()) == ["restarted extra", "restarted shift,twin"]

    # a graph edit of one node's entry restarts it alone
    graph.write_text(graph.read_text().replace("log_every: 0", "log_every: 1000"))
    wait_until(lambda: topics.reloads() == ["restarted sink"] or None, WAIT_S, "the sink was not restarted alone")

    graph.write_text(graph.read_text().replace(EXTRA, ""))  # a node removed: stopped
    wait_until(lambda: "reloaded: stopped extra" in output(), WAIT_S, "the removed node was not stopped")
    assert topics.reloads() == ["stopped extra"]
    assert output().count("started source") == 1


def test_an_edit_wins_over_the_values_set_while_running_for_the_keys_it_changed_or_refuses(tmp_path):
    old = load_graph(REPO / "configs/basic_chain.yaml")
    new = load_graph(REPO / "configs/basic_chain.yaml", text=old.path.read_text().replace("gain: 2.0", "gain: 4.0"))
    save_override(tmp_path, "scale", "gain", 3.0)
    save_override(tmp_path, "scale", "offset", 1.0)
    save_override(tmp_path, "source", "rate_hz", 20)
    save_override(tmp_path, "source", "amplitude", "loud")  # one the (edited) plugin refuses
    forget_edited_params(tmp_path, old, new)
    assert overrides_file(tmp_path, "scale").read_text() == '{"offset": 1.0}'
    assert overrides_file(tmp_path, "source").read_text() == '{"rate_hz": 20}'


def test_watch_is_refused_in_lockstep_mode():
    graph = load_graph(REPO / "configs/basic_chain.yaml")
    with pytest.raises(ValueError, match="--watch cannot be used in lock-step mode"):
        run_graph(graph, lockstep=True, watch=True)
