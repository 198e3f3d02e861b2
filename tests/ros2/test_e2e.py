"""`handflow run` with the ros2 option and plugins, against a raw Zenoh peer speaking rmw_zenoh (docs/ros2.md)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import zenoh

from handflow.framework.network.sessions import free_tcp_port
from handflow.framework.ros2 import rmw_zenoh as rz
from handflow.framework.ros2.types import own_msgs, type_hash

typesys = pytest.importorskip("rosbags.typesys")
pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]
JS, ARR = "sensor_msgs/msg/JointState", "handflow_msgs/msg/Array"


def _graph(tmp_path: Path, endpoint: str) -> Path:
    text = f"""name: ros_e2e
zenoh: {{connect: [{endpoint}]}}
ros2: {{domain_id: 3, publish: {{source/out: /source_out}}}}
nodes:
  - id: source
    plugin: basic.signal
    params: {{kind: sine, rate_hz: 50, width: 3}}
  - id: to-ros
    plugin: ros2.publish
    params: {{topic: /from_graph, type: {ARR}, domain_id: 3, connect: [{endpoint}]}}
    inputs: {{in: source/out}}
  - id: from-ros
    plugin: ros2.subscribe
    params: {{topic: /to_graph, type: {JS}, domain_id: 3, connect: [{endpoint}]}}
  - id: sink
    plugin: basic.sink
    params: {{jsonl: {tmp_path / "sink.jsonl"}}}
    inputs: {{in: from-ros/out}}
"""
    path = tmp_path / "graph.yaml"
    path.write_text(text)
    return path


def test_a_graph_talks_rmw_zenoh_both_ways(tmp_path):
    store = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    for name, text in own_msgs().items():
        store.register(typesys.get_types_from_msg(text, name))
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("listen/endpoints", json.dumps([endpoint]))
    ros = zenoh.open(conf)
    got: dict[str, list] = {"/source_out": [], "/from_graph": []}
    subs = [
        ros.declare_subscriber(
            rz.data_key(3, topic, ARR, type_hash(ARR)),
            lambda s, topic=topic: got[topic].append((s.payload.to_bytes(), s.attachment.to_bytes())),
        )
        for topic in got
    ]
    pub = ros.declare_publisher(rz.data_key(3, "/to_graph", JS, type_hash(JS)))
    m = store.types
    proc = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(_graph(tmp_path, endpoint)), "--duration", "4"],
        cwd=REPO,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        seq, tokens = 0, set()
        while proc.poll() is None:
            seq += 1
            stamp = m["builtin_interfaces/msg/Time"](sec=seq, nanosec=0)
            js = m[JS](
                header=m["std_msgs/msg/Header"](stamp=stamp, frame_id="ros_hand"),
                name=["a", "b"],
                position=np.array([0.1 * seq, -0.1 * seq]),
                velocity=np.zeros(0),
                effort=np.zeros(0),
            )
            pub.put(bytes(store.serialize_cdr(js, JS)), attachment=rz.pack_attachment(seq, time.time_ns(), bytes(16)))
            if seq % 20 == 0:
                tokens |= {str(r.ok.key_expr) for r in ros.liveliness().get("@ros2_lv/3/**") if r.ok is not None}
            time.sleep(0.02)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        for s in subs:
            s.undeclare()
        ros.close()
    assert proc.returncode == 0, err
    for topic, samples in got.items():
        assert len(samples) > 50, (topic, len(samples), err[-2000:])
        payload, att = samples[-1]
        assert store.deserialize_cdr(payload, ARR).data.size == 3
        assert rz.parse_attachment(att)[0] >= 50
    assert any("/MP/%/%/ros_e2e/%source_out/handflow_msgs::msg::dds_::Array_/" in t for t in tokens), tokens
    assert any("/MP/%/%/to_ros/%from_graph/" in t for t in tokens) and any(
        "/MS/%/%/from_ros/%to_graph/" in t for t in tokens
    )
    rows = [json.loads(line)["msg"] for line in (tmp_path / "sink.jsonl").read_text().splitlines()]
    assert len(rows) > 50 and rows[-1]["type"] == "handflow.JointState"
    assert rows[-1]["names"] == ["a", "b"] and rows[-1]["hand"] == "ros_hand"
    assert rows[-1]["header"]["stamp_ns"] % 1_000_000_000 == 0  # the ROS header's stamp (whole seconds here)
