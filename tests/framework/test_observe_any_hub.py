"""A reader joins any hub of a multi-machine graph and sees every machine (docs/tutorial_two_machines.md).

Two real launchers (hosts ``a`` and ``b`` of docs/examples/two_machines_*.yaml, on free ports) speak
mutual TLS; B reaches A through a TCP relay that counts the bytes on the A–B link, so the test sees
what crosses it with and without a reader.  Readers are real ``handflow monitor``/``record``
processes or real Zenoh sessions with the ``laptop`` certificate made by :mod:`handflow.framework.security.certs`.
"""

from __future__ import annotations

import json
import socket
import subprocess
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("cryptography")

from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.network.sessions import free_tcp_port
from handflow.framework.observe.monitor import Monitor
from handflow.framework.runtime.discovery import join_graphs, live_runs
from handflow.framework.security import certs

from ._rec_helpers import wait_counted, wait_until
from .test_runtime_e2e import start

pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]
TOPICS = ("handflow/two_machines/source/out", "handflow/two_machines/scale/out")


class Relay:
    """A TCP relay to ``127.0.0.1:target`` counting the bytes each way (``to_target``, ``from_target``)."""

    def __init__(self, target: int) -> None:
        self.target = target
        self.to_target = self.from_target = 0
        self._server = socket.create_server(("127.0.0.1", 0))
        self.port = self._server.getsockname()[1]
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self._server.accept()
                upstream = socket.create_connection(("127.0.0.1", self.target))
            except OSError:
                continue
            threading.Thread(target=self._pipe, args=(client, upstream, "to_target"), daemon=True).start()
            threading.Thread(target=self._pipe, args=(upstream, client, "from_target"), daemon=True).start()

    def _pipe(self, src: socket.socket, dst: socket.socket, counter: str) -> None:
        try:
            while data := src.recv(65536):
                setattr(self, counter, getattr(self, counter) + len(data))
                dst.sendall(data)
        except OSError:
            pass
        for s in (src, dst):
            s.close()

    def rate_to_target(self, seconds: float = 3.0) -> float:
        before = self.to_target
        time.sleep(seconds)
        return (self.to_target - before) / seconds


@pytest.fixture(scope="module")
def two_machines(tmp_path_factory):
    """Hosts a and b of the tutorial's graph running; b connects to a through a :class:`Relay` and listens too."""
    tmp = tmp_path_factory.mktemp("two_machines")
    ca = tmp / "certs"
    certs.init_ca(ca)
    for host in ("a", "b", "laptop", "mallory"):
        certs.add_host(ca, host)
    port_a, port_b = free_tcp_port(), free_tcp_port()
    relay = Relay(port_a)
    files = {}
    for host, old, new in (
        ("a", 'listen: ["tls/127.0.0.1:7457"]', f'listen: ["tls/127.0.0.1:{port_a}"]'),
        (
            "b",
            'connect: ["tls/127.0.0.1:7457"]',
            f'connect: ["tls/127.0.0.1:{relay.port}"]\n  listen: ["tls/127.0.0.1:{port_b}"]',
        ),
    ):
        text = (REPO / "docs" / "examples" / f"two_machines_{host}.yaml").read_text()
        assert old in text
        files[host] = tmp / f"two_machines_{host}.yaml"
        files[host].write_text(text.replace(old, new).replace("certs: certs", f"certs: {ca}"))
    run_dir = tmp / "runs"
    env_patch = pytest.MonkeyPatch()
    env_patch.setenv("HANDFLOW_RUN_DIR", str(run_dir))
    launchers = []
    try:
        for host in ("a", "b"):
            launchers.append(start("run", str(files[host]), "--host", host))
            deadline = time.time() + 30
            while len(live_runs()) < len(launchers):
                assert time.time() < deadline and launchers[-1].poll() is None, launchers[-1].communicate()
                time.sleep(0.2)
        session = join_graphs(None, f"tls/127.0.0.1:{port_a}", str(ca), "laptop")[0]
        try:  # both machines' nodes are up and linked: b's sink handles what a's source sends
            wait_counted(session, "two_machines", {"scale": "handled.in", "sink": "handled.in"})
        finally:
            session.close()
        yield {"ca": ca, "a": f"tls/127.0.0.1:{port_a}", "b": f"tls/127.0.0.1:{port_b}", "relay": relay}
    finally:
        for proc in reversed(launchers):
            proc.send_signal(2)
            try:
                proc.communicate(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
        env_patch.undo()


def _as(who: str, two_machines, hub: str = "a") -> list[str]:
    return ["--connect", two_machines[hub], "--certs", str(two_machines["ca"]), "--cert-name", who]


def test_the_link_carries_the_other_machines_topics_only_while_a_reader_subscribes(two_machines):
    relay = two_machines["relay"]
    alone = relay.rate_to_target()  # b -> a: health and progress of b's nodes only
    session, _, found = join_graphs(None, two_machines["a"], str(two_machines["ca"]), "laptop")
    monitor = Monitor(session, list(found))
    b_output = lambda: {t["topic"]: t["count"] for t in monitor.snapshot()["topics"]}.get(  # noqa: E731
        "handflow/two_machines/scale/out", 0
    )
    try:
        wait_until(lambda: b_output() > 0, timeout=30, what="b's output to reach the reader")
        watched = relay.rate_to_target()
        counts = {t["topic"]: t["count"] for t in monitor.snapshot()["topics"]}
    finally:
        monitor.close()
        session.close()
    quiet: list[float] = []  # the link's rate over 1 s windows once the reader has left, until it is b's own again
    wait_until(lambda: quiet.append(relay.rate_to_target(1.0)) or quiet[-1] < 1.25 * alone, 30, "the link to quiet")
    after = relay.rate_to_target()
    assert counts.get("handflow/two_machines/scale/out", 0) > 100, counts  # b's 50 Hz output reached the reader
    assert watched - alone > 50 * 50, (alone, watched)  # ... over the link: ≥ 50 B for each of 50 msg/s
    assert abs(after - alone) < 0.25 * alone, (alone, watched, quiet, after)  # and stops when the reader leaves


@pytest.mark.parametrize("hub", ["a", "b"])
@pytest.mark.parametrize("graph", [[], ["--graph", "two_machines"]], ids=["all-graphs", "--graph"])
def test_monitor_on_any_hub_shows_every_machines_topics_and_nodes(two_machines, hub, graph):
    proc = start("monitor", *_as("laptop", two_machines, hub), *graph, "--once", "--json")
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    snap = json.loads(out)
    counts = {t["topic"]: t["count"] for t in snap["topics"]}
    assert all(counts.get(t, 0) > 0 for t in TOPICS), counts
    assert {(n["graph"], n["id"]) for n in snap["nodes"] if n["alive"]} == {
        ("two_machines", nid) for nid in ("source", "scale", "sink")
    }


def test_record_as_the_laptop_records_both_machines(two_machines, tmp_path):
    out = tmp_path / "take.mcap"
    proc = start("record", "--out", str(out), "--duration", "2", *_as("laptop", two_machines))  # the only graph
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    topics = [rm.topic for rm in iter_recording(out)]
    assert all(topics.count(t) > 20 for t in TOPICS), {t: topics.count(t) for t in set(topics)}


@pytest.mark.parametrize(
    "case, options",
    [
        ("unreachable", ["--connect", "tls/127.0.0.1:{free}", "--certs", "{ca}", "--cert-name", "laptop"]),
        ("wrong scheme", ["--connect", "tcp/127.0.0.1:{port_a}"]),
        ("refused certificate", ["--connect", "{a}", "--certs", "{ca}", "--cert-name", "mallory"]),
    ],
)
@pytest.mark.parametrize("command", [["monitor", "--once", "--json"], ["record", "--out", "x.mcap", "--duration", "1"]])
def test_a_reader_that_reaches_no_graph_says_which_option_to_change(two_machines, tmp_path, case, options, command):
    values = {
        "free": free_tcp_port(),
        "ca": two_machines["ca"],
        "a": two_machines["a"],
        "port_a": two_machines["a"].rsplit(":", 1)[1],
    }
    proc = start(*command[:1], *[o.format(**values) for o in options], *command[1:])
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 2, (out, err)
    assert out == "" and "Traceback" not in err
    names = {"unreachable": "--connect", "wrong scheme": "--connect", "refused certificate": "--cert-name"}
    assert names[case] in err and "error: " in err, err


def test_several_graphs_on_one_hub_are_all_monitored_and_record_asks_which(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    launchers = []
    try:
        for name, zenoh in (("left", f"listen: [{endpoint}]"), ("right", f"connect: [{endpoint}]")):
            graph = tmp_path / f"{name}.yaml"
            graph.write_text(f"""name: {name}
zenoh: {{{zenoh}}}
nodes:
  - {{id: source, plugin: basic.signal, params: {{kind: sine, rate_hz: 50, width: 3}}}}
""")
            launchers.append(start("run", str(graph)))
            deadline = time.time() + 30
            while len(live_runs()) < len(launchers):
                assert time.time() < deadline and launchers[-1].poll() is None, launchers[-1].communicate()
                time.sleep(0.2)
        session = join_graphs(None, endpoint)[0]
        try:  # both graphs' sources publish
            for name in ("left", "right"):
                wait_counted(session, name, {"source": "published.out"})
        finally:
            session.close()
        monitor = start("monitor", "--connect", endpoint, "--once", "--json")
        out, err = monitor.communicate(timeout=60)
        record = start("record", "--connect", endpoint, "--out", str(tmp_path / "x.mcap"), "--duration", "1")
        _, record_err = record.communicate(timeout=60)
    finally:
        for proc in launchers:
            proc.send_signal(2)
            proc.communicate(timeout=30)
    assert monitor.returncode == 0, err
    counts = {t["topic"]: t["count"] for t in json.loads(out)["topics"]}
    assert counts.get("handflow/left/source/out", 0) > 0 and counts.get("handflow/right/source/out", 0) > 0, counts
    assert record.returncode == 2 and "several graphs run there (left, right)" in record_err, record_err
    assert "Traceback" not in record_err
