"""The live Foxglove bridge serves the 3D view: a real WebSocket client receives the URDF and TF of a running graph."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import time

import pytest

from handflow.framework.network.sessions import free_tcp_port
from handflow.framework.ros2.types import decode_cdr
from tests.conftest import REPO
from tests.foxglove_client import FoxgloveClient
from tests.simulator.test_viewer import assert_tree_matches_urdf

pytestmark = pytest.mark.slow
pytest.importorskip("foxglove")

GRAPH = """name: fx3d
nodes:
  - id: sim
    plugin: simulator.pybullet
    params: {hand: shadow, scene: cap, rate_hz: 10, camera_hz: 2, description_period_s: 0.5}
  - id: camera
    plugin: basic.compress_image
    inputs: {image: sim/image}
"""
WANTED = {
    "/handflow/fx3d/sim/tf": "tf2_msgs/msg/TFMessage",
    "/handflow/fx3d/sim/markers": "visualization_msgs/msg/MarkerArray",
    "/handflow/fx3d/sim/description": "std_msgs/msg/String",
    "/handflow/fx3d/camera/compressed": "sensor_msgs/msg/CompressedImage",
}


def test_live_bridge_serves_the_hand_description_tf_markers_and_jpeg(tmp_path):
    graph = tmp_path / "g.yaml"
    graph.write_text(GRAPH)
    port = free_tcp_port()
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "handflow.framework.cli",
            "run",
            str(graph),
            "--duration",
            "40",
            "--foxglove",
            str(port),
        ],
        cwd=REPO,
        stderr=subprocess.PIPE,
        text=True,
    )
    channels: dict[str, dict] = {}
    received: dict[str, bytes] = {}
    try:
        deadline = time.time() + 35
        with FoxgloveClient(port, deadline - time.time()) as fox:  # it subscribes again when refused
            subscribed: dict[int, str] = {}
            while time.time() < deadline and len(received) < len(WANTED):
                try:
                    frame = fox.recv(timeout=1)
                except TimeoutError:
                    continue
                if isinstance(frame, str):
                    msg = json.loads(frame)
                    if msg.get("op") == "advertise":
                        for ch in msg["channels"]:
                            if ch["topic"] in WANTED and ch["topic"] not in channels:
                                channels[ch["topic"]] = ch
                                subscribed[len(subscribed) + 1] = ch["topic"]
                                fox.send(op="subscribe", subscriptions=[{"id": len(subscribed), "channelId": ch["id"]}])
                elif frame[0] == 0x01:  # message data: opcode, subscription id, receive time, payload
                    (sub,) = struct.unpack_from("<I", frame, 1)
                    received.setdefault(subscribed[sub], bytes(frame[13:]))
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=30)
    assert set(received) == set(WANTED), (sorted(received), err[-2000:])
    assert fox.problems() == [], fox.problems()
    for topic, schema in WANTED.items():
        assert (channels[topic]["schemaName"], channels[topic]["encoding"]) == (schema, "cdr")
    tf = decode_cdr(received["/handflow/fx3d/sim/tf"], WANTED["/handflow/fx3d/sim/tf"])
    urdf = decode_cdr(received["/handflow/fx3d/sim/description"], WANTED["/handflow/fx3d/sim/description"]).data
    assert_tree_matches_urdf(tf, urdf)
    markers = decode_cdr(received["/handflow/fx3d/sim/markers"], WANTED["/handflow/fx3d/sim/markers"])
    assert markers.kinds == ["cylinder", "cylinder"]
    jpeg = decode_cdr(received["/handflow/fx3d/camera/compressed"], WANTED["/handflow/fx3d/camera/compressed"])
    assert jpeg.format == "jpeg" and jpeg.data[:2] == b"\xff\xd8"
