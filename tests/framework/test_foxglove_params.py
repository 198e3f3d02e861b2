"""Foxglove's Parameters panel on a running graph (docs/tuning.md): a real ``foxglove.websocket.v1`` client
gets, sets and is refused parameters of `handflow run --foxglove`, and sees changes made by `handflow param`."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from websockets.sync.client import connect

from handflow.framework.network.sessions import free_tcp_port

pytest.importorskip("foxglove")
pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]


class FoxgloveClient:
    """The Foxglove app's side of the protocol: JSON requests, replies picked by their ``op``."""

    def __init__(self, port: int, timeout: float = 30.0) -> None:
        deadline = time.time() + timeout
        while True:
            try:
                self.ws = connect(
                    f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"], open_timeout=2
                )
                break
            except OSError:
                if time.time() > deadline:
                    raise
                time.sleep(0.3)

    def __enter__(self) -> FoxgloveClient:
        self.ws.__enter__()
        self.server_info = self.next("serverInfo")
        return self

    def __exit__(self, *exc) -> None:
        self.ws.__exit__(*exc)

    def send(self, **msg) -> None:
        self.ws.send(json.dumps(msg))

    def next(self, op: str, timeout: float = 15.0, **match) -> dict:
        deadline = time.time() + timeout
        while time.time() < deadline:
            try:
                frame = self.ws.recv(timeout=1)
            except TimeoutError:
                continue
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg.get("op") == op and all(msg.get(k) == v for k, v in match.items()):
                    return msg
        raise AssertionError(f"no {op} {match} within {timeout}s")

    def values(self, **request) -> dict[str, object]:
        msg = self.next("parameterValues", id=request.get("id"))
        return {p["name"]: p.get("value") for p in msg["parameters"]}


def test_parameters_panel_gets_sets_and_is_refused_with_the_models_message(tmp_path):
    graph = tmp_path / "g.yaml"
    graph.write_text(
        "name: fxp\nnodes:\n  - id: source\n    plugin: basic.signal\n    params: {rate_hz: 20}\n"
        "  - id: scale\n    plugin: basic.transform\n    params: {gain: 2.0}\n    inputs: {in: source/out}\n"
    )
    env = dict(os.environ, HANDFLOW_RUN_DIR=str(tmp_path / "runs"))
    port = free_tcp_port()
    cli = [sys.executable, "-m", "handflow.framework.cli"]
    run = subprocess.Popen(
        [*cli, "run", str(graph), "--duration", "40", "--foxglove", str(port)],
        cwd=REPO,
        env=env,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        with FoxgloveClient(port) as fox:
            check_parameters_panel(fox, cli, env)
    finally:
        run.terminate()
        _, err = run.communicate(timeout=60)
    assert run.returncode == 0, err


def check_parameters_panel(fox: FoxgloveClient, cli: list[str], env: dict) -> None:
    """What the Parameters panel does, and `handflow param` beside it."""
    assert "parameters" in fox.server_info["capabilities"]
    params: dict = {}
    for attempt in range(60):  # until the nodes are up
        fox.send(op="getParameters", parameterNames=[], id=f"all{attempt}")
        if "/scale/gain" in (params := fox.values(id=f"all{attempt}")):
            break
        time.sleep(0.5)
    assert params["/scale/gain"] == 2.0 and params["/source/kind"] == "sine" and params["/source/rate_hz"] == 20

    fox.send(op="subscribeParameterUpdates", parameterNames=["/scale/gain"])
    fox.send(op="setParameters", parameters=[{"name": "/scale/gain", "value": 3.0}], id="set")
    assert fox.values(id="set") == {"/scale/gain": 3.0}
    cli_get = subprocess.run([*cli, "param", "get", "scale.gain"], env=env, capture_output=True, text=True)
    assert cli_get.stdout.strip() == "3"

    fox.send(op="setParameters", parameters=[{"name": "/scale/gain", "value": "notanumber"}], id="bad")
    status = fox.next("status")
    assert status["level"] == 2 and "/scale/gain not set" in status["message"]
    assert "valid number" in status["message"]  # the model's message
    assert fox.values(id="bad") == {"/scale/gain": 3.0}  # the old value kept
    fox.send(op="setParameters", parameters=[{"name": "/source/rate_hz", "value": 5.0}], id="start-only")
    assert "needs a restart" in fox.next("status")["message"]
    assert fox.values(id="start-only") == {"/source/rate_hz": 20.0}

    subprocess.run([*cli, "param", "set", "scale.gain", "4.5"], env=env, check=True, capture_output=True)
    update = fox.next("parameterValues")  # a change made elsewhere reaches the subscribed panel
    assert {p["name"]: p["value"] for p in update["parameters"]} == {"/scale/gain": 4.5}


def test_topic_graph_shows_every_hosts_nodes_and_edges(tmp_path):
    """Foxglove's Topic Graph panel (ConnectionGraph) on the launcher of host a of a two-host graph."""
    graph = tmp_path / "g.yaml"
    graph.write_text(
        "name: fxg\nexternal: {glove/raw: Array}\nnodes:\n"
        "  - {id: source, plugin: basic.signal, host: a, params: {rate_hz: 20}}\n"
        "  - {id: scale, plugin: basic.transform, host: b, inputs: {in: source/out}}\n"
        "  - {id: sink, plugin: basic.sink, host: a, inputs: {in: scale/out}}\n"
        "  - {id: raw, plugin: basic.sink, host: a, inputs: {in: glove/raw}}\n"
    )
    port = free_tcp_port()
    run = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(graph), "--host", "a"]
        + ["--duration", "20", "--foxglove", str(port)],
        cwd=REPO,
        env=dict(os.environ, HANDFLOW_RUN_DIR=str(tmp_path / "runs")),
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        with FoxgloveClient(port) as fox:
            assert "connectionGraph" in fox.server_info["capabilities"]
            fox.send(op="subscribeConnectionGraph")
            update = fox.next("connectionGraphUpdate")
    finally:
        run.terminate()
        _, err = run.communicate(timeout=60)
    assert run.returncode == 0, err
    published = {t["name"]: t["publisherIds"] for t in update["publishedTopics"]}
    subscribed = {t["name"]: t["subscriberIds"] for t in update["subscribedTopics"]}
    assert published == {
        "/handflow/fxg/source/out": ["a/source"],
        "/handflow/fxg/scale/out": ["b/scale"],  # a node of the other host
    }
    assert subscribed == {
        "/handflow/fxg/source/out": ["b/scale"],
        "/handflow/fxg/scale/out": ["a/sink"],
        "/handflow/fxg/glove/raw": ["a/raw"],  # fed from outside the graph: no publisher
    }
