"""ros2.subscribe / ros2.publish against raw Zenoh peers speaking rmw_zenoh (docs/ros2.md)."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
import zenoh
from hypothesis import given
from hypothesis import strategies as st

from handflow.framework.graphs.model import read_graph_text
from handflow.framework.messages import Array, JointState, MessageError
from handflow.framework.network.sessions import free_tcp_port
from handflow.framework.ros2 import rmw_zenoh as rz
from handflow.framework.ros2.types import type_hash
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.ros2.codec import RosCodec
from handflow.plugins.ros2.nodes import Ros2Publish, Ros2Subscribe

typesys = pytest.importorskip("rosbags.typesys")
STORE = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
JS = "sensor_msgs/msg/JointState"


@pytest.fixture
def ros_side():
    """A raw Zenoh peer standing in for the ROS 2 system's router; yields (session, endpoint)."""
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("listen/endpoints", json.dumps([endpoint]))
    session = zenoh.open(conf)
    yield session, endpoint
    session.close()


def _wait(pred, timeout=5.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.02)
    return False


def _ros_joint_state(names, positions, sec=12, nanosec=34):
    m = STORE.types
    header = m["std_msgs/msg/Header"](stamp=m["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id="base")
    msg = m[JS](
        header=header, name=names, position=np.asarray(positions, float), velocity=np.zeros(0), effort=np.zeros(0)
    )
    return bytes(STORE.serialize_cdr(msg, JS))


def test_publish_reaches_a_raw_rmw_zenoh_subscriber(ros_side):
    session, endpoint = ros_side
    key = rz.data_key(0, "/hand/joint_states", JS, type_hash(JS))
    got = []
    sub = session.declare_subscriber(key, lambda s: got.append((s.payload.to_bytes(), s.attachment.to_bytes())))
    h = NodeHarness(Ros2Publish, {"topic": "/hand/joint_states", "type": JS, "connect": [endpoint]}, node_id="to-ros")
    h.setup()
    try:
        msg = JointState(names=["j0", "j1"], positions=np.array([0.5, -0.25]), hand="human")
        assert _wait(lambda: (h.send("in", msg, stamp_ns=7_000_000_001), bool(got))[1])
        payload, att = got[-1]
        ros = STORE.deserialize_cdr(payload, JS)
        assert ros.name == ["j0", "j1"] and list(ros.position) == [0.5, -0.25]
        assert (ros.header.stamp.sec, ros.header.stamp.nanosec) == (7, 1)
        assert bytes(STORE.serialize_cdr(ros, JS)) == payload
        seq, _, gid = rz.parse_attachment(att)
        assert 1 <= seq <= h.node.publisher.seq and gid == h.node.publisher.gid
        tokens = {str(r.ok.key_expr) for r in session.liveliness().get("@ros2_lv/0/**") if r.ok is not None}
        assert h.node.publisher.token_key in tokens and h.node.ros_node.token_key in tokens
        assert "/NN/%/%/to_ros" in h.node.ros_node.token_key
        h.send("in", Array(data=np.ones(2)))  # not a JointState: dropped with a reason
        assert "published from handflow.JointState" in h.dropped[-1][1]
    finally:
        sub.undeclare()
        h.teardown()


def test_subscribe_brings_a_raw_rmw_zenoh_publisher_into_the_graph(ros_side):
    session, endpoint = ros_side
    h = NodeHarness(Ros2Subscribe, {"topic": "/joint_states", "type": JS, "connect": [endpoint]}, node_id="from-ros")
    h.setup()
    try:
        key = rz.data_key(0, "/joint_states", JS, type_hash(JS))
        pub = session.declare_publisher(key)
        gid = bytes(16)
        seq = iter(range(1, 10_000))

        def send(payload, att=True):
            pub.put(payload, attachment=rz.pack_attachment(next(seq), 5, gid) if att else None)

        assert _wait(lambda: (send(_ros_joint_state(["a", "b"], [1.0, 2.0])), h.tick(), bool(h.published["out"]))[2])
        msg = h.published["out"][0]
        assert isinstance(msg, JointState) and msg.names == ["a", "b"] and list(msg.positions) == [1.0, 2.0]
        assert msg.header.stamp_ns == 12_000_000_034 and msg.hand == "base"
        n = len(h.published["out"])
        send(b"\x00\x01\x00\x00garbage")  # malformed CDR
        send(_ros_joint_state(["a"], [1.0]), att=False)  # no attachment
        session.put(key.rsplit("/", 1)[0] + "/RIHS01_" + "0" * 64, _ros_joint_state(["a"], [1.0]))  # other definition
        assert _wait(lambda: (h.tick(), h.node.rejected >= 3)[1])
        assert len(h.published["out"]) == n or all(m.names == ["a", "b"] for m in h.published["out"][n:])
    finally:
        h.teardown()


def test_any_store_type_comes_in_as_a_named_array_and_goes_back(ros_side):
    session, endpoint = ros_side
    params = {"topic": "/pose", "type": "geometry_msgs/msg/PoseStamped", "connect": [endpoint]}
    h = NodeHarness(Ros2Subscribe, params)
    assert Ros2Subscribe.output_types(h.node.params) == {"out": Array}
    h.setup()
    out = NodeHarness(Ros2Publish, {**params, "topic": "/pose_out"})
    out.setup()
    got = []
    codec = RosCodec("geometry_msgs/msg/PoseStamped")
    sub = session.declare_subscriber(
        rz.data_key(0, "/pose_out", codec.ros_type, codec.type_hash), lambda s: got.append(s.payload.to_bytes())
    )
    try:
        m = STORE.types
        pose = m["geometry_msgs/msg/PoseStamped"](
            header=m["std_msgs/msg/Header"](stamp=m["builtin_interfaces/msg/Time"](sec=3, nanosec=4), frame_id="w"),
            pose=m["geometry_msgs/msg/Pose"](
                position=m["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=3.0),
                orientation=m["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )
        cdr = bytes(STORE.serialize_cdr(pose, "geometry_msgs/msg/PoseStamped"))
        pub = session.declare_publisher(rz.data_key(0, "/pose", codec.ros_type, codec.type_hash))
        assert _wait(
            lambda: (pub.put(cdr, attachment=rz.pack_attachment(1, 0, bytes(16))), h.tick(), bool(h.published["out"]))[
                2
            ]
        )
        arr = h.published["out"][0]
        assert arr.names[:3] == ["pose.position.x", "pose.position.y", "pose.position.z"]
        assert list(arr.data) == [1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0] and arr.header.stamp_ns == 3_000_000_004
        assert _wait(lambda: (out.send("in", arr, stamp_ns=arr.header.stamp_ns), bool(got))[1])
        back = STORE.deserialize_cdr(got[-1], "geometry_msgs/msg/PoseStamped")
        assert (back.pose.position.x, back.pose.position.z, back.pose.orientation.w) == (1.0, 3.0, 1.0)
        assert (back.header.stamp.sec, back.header.stamp.nanosec) == (3, 4)
    finally:
        sub.undeclare()
        h.teardown()
        out.teardown()


def test_msg_files_add_types(tmp_path):
    f = tmp_path / "lab_msgs" / "msg" / "Emg.msg"
    f.parent.mkdir(parents=True)
    f.write_text("std_msgs/Header header\nfloat32[] channels\nuint8 quality\n")
    codec = RosCodec("lab_msgs/msg/Emg", [f])
    arr = Array(data=np.array([0.5, 0.25, 3.0]), names=["channels[0]", "channels[1]", "quality"])
    back = codec.decode(codec.encode(arr), "s", 1, 0)
    assert back.names == arr.names and list(back.data) == [0.5, 0.25, 3.0]
    with pytest.raises(MessageError, match="give its .msg file"):
        RosCodec("lab_msgs/msg/Other")
    with pytest.raises(MessageError, match="no field 'nope'"):
        codec.encode(Array(data=np.ones(1), names=["nope"]))
    with pytest.raises(MessageError, match="<package>/msg/<Name>.msg"):
        RosCodec("lab_msgs/msg/Emg", [tmp_path / "Emg.msg"])


def test_graph_types_the_subscribe_output_by_the_ros_type(tmp_path):
    text = """
name: g
nodes:
  - {id: js, plugin: ros2.subscribe, params: {topic: /joint_states, type: sensor_msgs/msg/JointState}}
  - {id: pose, plugin: ros2.subscribe, params: {topic: /pose, type: geometry_msgs/msg/PoseStamped}}
  - {id: sel, plugin: basic.select, inputs: {primary: js/out, secondary: pose/out}}
"""
    graph, problems = read_graph_text(text, tmp_path / "g.yaml")
    assert graph is None and len(problems) == 1
    assert "'secondary' expects handflow.JointState but 'pose/out' publishes handflow.Array" in problems[0].message
    _, problems = read_graph_text(text.replace("/joint_states, type", "joint_states, type"), tmp_path / "g.yaml")
    assert any("must start with '/'" in p.message for p in problems)
    out = text.replace("plugin: basic.select, inputs: {primary: js/out, secondary: pose/out}", "plugin: ros2.publish")
    out = out.replace(
        "- {id: sel, plugin: ros2.publish}",
        "- {id: sel, plugin: ros2.publish, inputs: {in: pose/out}, params: {topic: /j, type: sensor_msgs/msg/JointState}}",
    )
    _, problems = read_graph_text(out, tmp_path / "g.yaml")
    assert [p.message for p in problems] == [
        "node 'sel' input 'in' expects handflow.JointState but 'pose/out' publishes handflow.Array; connect a matching output"
    ]


CODECS = [RosCodec(JS), RosCodec("geometry_msgs/msg/PoseStamped"), RosCodec("sensor_msgs/msg/Imu")]


@given(st.integers(0, len(CODECS) - 1), st.binary(max_size=400))
def test_any_bytes_from_ros_decode_or_raise_message_error(which, data):
    try:
        msg = CODECS[which].decode(b"\x00\x01\x00\x00" + data, "ros2:/t", 1, 0)
    except MessageError:
        return
    msg.check()
