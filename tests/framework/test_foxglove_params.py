"""Foxglove's Parameters panel on a running graph (docs/tuning.md, docs/foxglove.md): a real ``foxglove.sdk.v1``
client gets every parameter (``null`` ones as ``""``, integers as integers), sets and is refused parameters of
`handflow run --foxglove`, and sees changes made by `handflow param`; a client offering only the old
subprotocol is refused and the terminal says which one it needs."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from handflow.framework.files.mcap_writer import McapWriter
from handflow.framework.messages import Array, Header
from handflow.framework.network.sessions import free_tcp_port
from tests.foxglove_client import (
    FoxgloveClient,
    connect_foxglove,
    handflow_with_foxglove,
    playback_request,
    playback_state,
)

pytest.importorskip("foxglove")
pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]


def test_parameters_panel_gets_sets_and_is_refused_with_the_models_message(tmp_path):
    graph = tmp_path / "g.yaml"
    graph.write_text(
        "name: fxp\nnodes:\n  - id: source\n    plugin: basic.signal\n    params: {rate_hz: 20}\n"
        "  - id: scale\n    plugin: basic.transform\n    params: {gain: 2.0}\n    inputs: {in: source/out}\n"
    )
    env = dict(os.environ, HANDFLOW_RUN_DIR=str(tmp_path / "runs"))
    cli = [sys.executable, "-m", "handflow.framework.cli"]
    run, port = handflow_with_foxglove(["run", str(graph), "--duration", "40"], env, REPO)
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
    for attempt in range(60):  # until both nodes are up and answer
        fox.send(op="getParameters", parameterNames=[], id=f"all{attempt}")
        if {"/scale/gain", "/source/kind"} <= (params := fox.values(id=f"all{attempt}")).keys():
            break
        time.sleep(0.5)
    assert params["/scale/gain"] == 2.0 and params["/source/kind"] == "sine" and params["/source/rate_hz"] == 20
    assert isinstance(params["/source/width"], int) and isinstance(params["/source/rate_hz"], float)  # as declared

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
    fox.send(op="setParameters", parameters=[{"name": "/source/rate_hz", "value": 5}], id="start-only")
    refused = fox.next("status")["message"]
    assert "only at start" in refused and "handflow param set source.rate_hz 5 --restart" in refused, refused
    assert fox.values(id="start-only") == {"/source/rate_hz": 20}

    subprocess.run([*cli, "param", "set", "scale.gain", "4.5"], env=env, check=True, capture_output=True)
    update = fox.next("parameterValues")  # a change made elsewhere reaches the subscribed panel
    assert {p["name"]: p["value"] for p in update["parameters"]} == {"/scale/gain": 4.5}


def test_null_parameters_are_listed_set_and_set_back_and_an_old_client_is_told_the_subprotocol(tmp_path):
    """The flagship's segmenter (configs/demo_segment_only.yaml, fed by nothing): every parameter of every
    node is listed as `handflow param list` lists it, `/segmenter/background_factor` (null) as "";
    set to 2 and back to null with "", `handflow param get` follows."""
    env = dict(os.environ, HANDFLOW_RUN_DIR=str(tmp_path / "runs"))
    cli = [sys.executable, "-m", "handflow.framework.cli"]
    graph = str(REPO / "configs" / "demo_segment_only.yaml")
    run, port = handflow_with_foxglove(["run", graph, "--duration", "60"], env, tmp_path)
    key = "/segmenter/background_factor"

    def param_get() -> str:
        got = subprocess.run([*cli, "param", "get", "segmenter.background_factor"], env=env, capture_output=True)
        return got.stdout.decode().strip()

    try:
        with FoxgloveClient(port, timeout=60) as fox:
            with pytest.raises(InvalidStatus, match="400"):  # an app offering only the old name
                connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.websocket.v1"], open_timeout=5)
            listed: dict = {}
            for attempt in range(120):  # until both nodes answer
                fox.send(op="getParameters", parameterNames=[], id=f"all{attempt}")
                if {key, "/labels/jsonl"} <= (listed := fox.values(id=f"all{attempt}")).keys():
                    break
                time.sleep(0.5)
            cli_list = subprocess.run([*cli, "param", "list"], env=env, capture_output=True, text=True).stdout
            assert listed[key] == "" and listed["/segmenter/distance_z"] == ""
            fox.send(op="setParameters", parameters=[{"name": key, "value": 2}], id="two")
            assert fox.values(id="two") == {key: 2.0}
            assert param_get() == "2"
            fox.send(op="setParameters", parameters=[{"name": key, "value": ""}], id="back")  # null, as documented
            assert fox.values(id="back") == {key: ""}
            assert param_get() == "null"
            problems = fox.problems()
    finally:
        run.terminate()
        _, err = run.communicate(timeout=60)
    assert run.returncode == 0, err
    assert problems == []
    names = {"/" + line.split(" = ")[0].replace(".", "/", 1) for line in cli_list.splitlines() if " = " in line}
    assert len(names) > 20 and names == set(listed), cli_list  # every parameter of every node, whatever its value
    assert "handshake failed" in err and "foxglove.sdk.v1" in err.split("handshake failed", 1)[1], err


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
    env = dict(os.environ, HANDFLOW_RUN_DIR=str(tmp_path / "runs"))
    run, port = handflow_with_foxglove(["run", str(graph), "--host", "a", "--duration", "20"], env, REPO)
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


def test_replay_is_driven_from_the_playback_bar(tmp_path):
    """`handflow replay F.mcap --into G.yaml --foxglove`: pause, seek and speed from a real Foxglove client;
    the replayed topic and the graph's node follow.  The graph's own `foxglove:` server is not opened."""
    start = 1_700_000_000_000_000_000
    with McapWriter(tmp_path / "take.mcap") as writer:
        for i in range(1000):  # 20 s at 50 Hz, data = the index
            msg = Array(data=[float(i)])
            msg.header = Header("source", i + 1, start + i * 20_000_000)
            writer.write("handflow/pb/source/out", msg, log_time_ns=msg.header.stamp_ns)
    graph = tmp_path / "g.yaml"
    own_port = free_tcp_port()
    graph.write_text(
        f"name: pb\nfoxglove: {{port: {own_port}}}\nexternal: {{source/out: Array}}\nnodes:\n"
        f"  - id: sink\n    plugin: basic.sink\n    params: {{jsonl: {tmp_path / 'sink.jsonl'}}}\n"
        "    inputs: {in: source/out}\n"
    )
    env = dict(os.environ, HANDFLOW_RUN_DIR=str(tmp_path / "runs"))
    replay, port = handflow_with_foxglove(["replay", str(tmp_path / "take.mcap"), "--into", str(graph)], env, REPO)
    try:
        with FoxgloveClient(port) as fox:
            assert "playbackControl" in fox.server_info["capabilities"]
            channel = None
            while channel is None:  # the sink's heartbeat may be advertised first
                advertised = fox.next("advertise")["channels"]
                channel = next((c for c in advertised if c["topic"] == "/handflow/pb/source/out"), None)
            fox.send(op="subscribe", subscriptions=[{"id": 7, "channelId": channel["id"]}])
            playing = len(fox.binary(opcode=1, seconds=1.0))
            fox.ws.send(playback_request(1, 1.0, None, "pause"))
            paused = fox.binary(opcode=5, seconds=0.5)
            held = len(fox.binary(opcode=1, seconds=1.0))
            seek = start + 12 * 10**9  # message 600
            fox.ws.send(playback_request(0, 4.0, seek, "seek"))
            answer, state = (playback_state(f) for f in fox.binary(opcode=5, seconds=0.5))  # reaching it, playing
            fast = len(fox.binary(opcode=1, seconds=1.0))
            with pytest.raises(OSError):  # one server: the replay's, not the graph's
                connect_foxglove(own_port, timeout=0)
    finally:
        replay.send_signal(signal.SIGINT)
        _, err = replay.communicate(timeout=60)
    assert replay.returncode == 0, err
    assert fox.problems() == [] and " ERROR " not in err, err  # every request answered with a playback state
    assert [st["id"] for st in fox.states if st["id"]] == [b"pause", b"seek"]
    assert 30 <= playing <= 70  # 50 Hz
    assert playback_state(paused[0]) | {"time": 0} == {
        "status": 1,
        "time": 0,
        "speed": 1.0,
        "did_seek": False,
        "id": b"pause",
    }
    assert held <= 2  # paused: nothing more (a message in flight at most)
    assert (answer["status"], answer["did_seek"], answer["speed"], answer["time"]) == (2, True, 4.0, seek)  # buffering
    assert (state["status"], state["did_seek"], state["speed"]) == (0, False, 4.0)
    assert seek <= state["time"] < seek + 10**8  # the target (playing on from it)
    assert 130 <= fast <= 250  # 4× speed: 200 a second
    handled = [json.loads(line)["msg"]["data"][0] for line in (tmp_path / "sink.jsonl").read_text().splitlines()]
    jump = next(i for i in range(1, len(handled)) if handled[i] != handled[i - 1] + 1)
    assert handled[jump] == 600.0 and handled[:jump] == list(range(jump))  # the graph's node followed the seek
