"""rmw_zenoh interop: RIHS01 hashes, keys, tokens and attachments against independent sources (docs/ros2.md)."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
import zenoh
import zenoh.ext as zext
from hypothesis import given
from hypothesis import strategies as st

from handflow.framework import wire
from handflow.framework.cli import main
from handflow.framework.graphs.model import read_graph_text
from handflow.framework.messages import Array, Header, JointState, MessageError
from handflow.framework.network.sessions import free_tcp_port
from handflow.framework.ros2 import rmw_zenoh as rz
from handflow.framework.ros2.type_hash import full_name, rihs01
from handflow.framework.ros2.types import STANDARD_MSGS, own_msgs, type_hash
from handflow.framework.runtime.ros2_bridge import Ros2Bridge

typesys = pytest.importorskip("rosbags.typesys")

# Published values: rmw_zenoh's docs/design.md (String) and `ros2 topic info --verbose` of a Jazzy system (JointState).
STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
JOINT_STATE_HASH = "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
# Examples quoted in rmw_zenoh's docs/design.md (Jazzy): a talker's publisher and a listener node.
TALKER_TOKEN = (
    "@ros2_lv/0/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/"
    f"{STRING_HASH}/::,7:,:,:,,"
)
LISTENER_TOKEN = "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"


@pytest.fixture(scope="module")
def store():
    ts = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    types = {}
    for name, text in own_msgs().items():
        types.update(typesys.get_types_from_msg(text, name))
    ts.register(types)
    return ts


def _texts(store, name):
    text, _ = store.generate_msgdef(name, ros_version=2)
    first, *deps = text.split("=" * 80 + "\n")
    out = {name: first}
    for dep in deps:
        head, _, body = dep.partition("\n")
        out[full_name(head.removeprefix("MSG: ").strip())] = body
    return out


def test_hashes_equal_published_values():
    assert rihs01("std_msgs/msg/String", {"std_msgs/msg/String": "string data"}) == STRING_HASH
    assert type_hash("sensor_msgs/msg/JointState") == JOINT_STATE_HASH


def test_hashes_equal_rosbags_for_every_jazzy_type_and_handflow_msgs(store):
    uses_char = []
    for name in store.fielddefs:
        texts = _texts(store, name)
        if any(
            line.split()[:1] and line.split()[0].startswith("char") for t in texts.values() for line in t.splitlines()
        ):
            uses_char.append(name)  # rosbags hashes .msg `char` as CHAR; rosidl maps it to uint8 (docs/ros2.md)
            continue
        assert rihs01(name, texts) == store.hash_rihs01(name), name
    assert len(store.fielddefs) - len(uses_char) > 150
    for name in [*own_msgs(), *STANDARD_MSGS]:
        assert type_hash(name) == store.hash_rihs01(name), name


def test_hash_reads_bounds_constants_defaults_and_empty_types():
    a = rihs01("p/msg/A", {"p/msg/A": "int32 X=1\nstring<=8 s\nfloat64[3] v\nuint8[<=4] b\nfloat64 w 1.0"})
    b = rihs01("p/msg/A", {"p/msg/A": "string<=8 s\nfloat64[3] v\nuint8[<=4] b\nfloat64 w"})
    assert a == b  # constants and default values are not hashed
    assert rihs01("p/msg/A", {"p/msg/A": "string s\nfloat64[3] v\nuint8[<=4] b\nfloat64 w"}) != a
    assert rihs01("p/msg/E", {"p/msg/E": "# nothing"}) == rihs01(
        "p/msg/E", {"p/msg/E": "uint8 structure_needs_at_least_one_member"}
    )
    with pytest.raises(MessageError, match="no definition of p/msg/B"):
        rihs01("p/msg/A", {"p/msg/A": "B b"})


def test_keys_and_tokens_match_rmw_zenoh_examples():
    assert rz.data_key(0, "/chatter", "std_msgs/msg/String", STRING_HASH) == (
        f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    )
    assert (
        rz.data_key(3, "/robot1/chatter", "std_msgs/msg/String", "H")
        == "3/robot1/chatter/std_msgs::msg::dds_::String_/H"
    )
    zid = "8b20917502ee955ac4476e0266340d5c"
    tok = rz.endpoint_token(
        "MP", 0, zid, 0, 10, "talker", "/chatter", "std_msgs/msg/String", STRING_HASH, rz.qos_chunk(7)
    )
    assert tok == TALKER_TOKEN
    assert rz.node_token(0, "aac3178e146ba6f1fc6e6a4085e77f21", 0, "listener") == LISTENER_TOKEN
    assert rz.split_data_key(f"0/a/b/T_/{STRING_HASH}") == (0, "/a/b", "T_", STRING_HASH)
    for bad in ("chatter", "/a//b", "/1a", "/a-b", "/a/"):
        with pytest.raises(MessageError, match="must start with '/'"):
            rz.check_name(bad)


def test_tokens_parse_back_into_entities():
    pub = rz.parse_token(TALKER_TOKEN)
    assert (pub.kind, pub.domain_id, pub.node, pub.namespace) == ("MP", 0, "talker", "/")
    assert (pub.topic, pub.ros_type, pub.type_hash) == ("/chatter", "std_msgs/msg/String", STRING_HASH)
    assert rz.parse_token(LISTENER_TOKEN) == rz.Entity("NN", 0, "aac3178e146ba6f1fc6e6a4085e77f21", "listener", "/")
    for bad in ("@ros2_lv/0/z/0/1/MP/%/%/n", "handflow/g/n/p", "@ros2_lv/x/z/0/0/NN/%/%/n"):
        with pytest.raises(MessageError):
            rz.parse_token(bad)


def test_ros2_topics_command_lists_what_ros2_topic_list_would(capsys):
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    router, peer = _session(listen=[endpoint]), _session(connect=[endpoint])
    node = rz.RosNode(peer, "lister", domain_id=4)
    node.publisher("/hand/joint_states", "sensor_msgs/msg/JointState", JOINT_STATE_HASH)
    node.subscriber("/hand/joint_states", "sensor_msgs/msg/JointState", JOINT_STATE_HASH, lambda *a: None)
    node.publisher("/chatter", "std_msgs/msg/String", STRING_HASH)
    try:
        args = ["ros2-topics", "--connect", endpoint, "--domain-id", "4", "--timeout", "1", "--json"]
        for _ in range(20):
            assert main(args) == 0
            table = json.loads(capsys.readouterr().out)
            if len(table) == 2:
                break
            time.sleep(0.1)
        assert table == {
            "/chatter": {"type": "std_msgs/msg/String", "type_hash": STRING_HASH, "publishers": 1, "subscriptions": 0},
            "/hand/joint_states": {
                "type": "sensor_msgs/msg/JointState",
                "type_hash": JOINT_STATE_HASH,
                "publishers": 1,
                "subscriptions": 1,
            },
        }
    finally:
        node.close()
        peer.close()
        router.close()
    assert main(["ros2-topics", "--connect", "tcp/127.0.0.1:1", "--timeout", "0.2"]) == 2
    assert "start its router" in capsys.readouterr().out


def test_attachment_is_zenoh_ext_serialisation():
    gid = bytes(range(16))
    ours = rz.pack_attachment(5, 1_700_000_000_123, gid)
    theirs = zext.z_serialize((zext.Int64(5), zext.Int64(1_700_000_000_123), gid)).to_bytes()
    assert ours == theirs and len(ours) == 33
    assert rz.parse_attachment(ours) == (5, 1_700_000_000_123, gid)
    keyed = (  # the layout of rmw_zenoh for Jazzy up to 0.2.3 (fields named), still read
        "sequence_number",
        zext.Int64(5),
        "source_timestamp",
        zext.Int64(1_700_000_000_123),
        "source_gid",
        gid,
    )
    assert rz.parse_attachment(zext.z_serialize(keyed).to_bytes()) == (5, 1_700_000_000_123, gid)


@given(st.binary(max_size=64))
def test_any_attachment_bytes_parse_or_raise_message_error(data):
    try:
        seq, _, gid = rz.parse_attachment(data)
    except MessageError:
        return
    assert len(gid) == 16 and isinstance(seq, int)


# ----------------------------------------------------------------------------------------------
# The graph-level option, on real Zenoh sessions
# ----------------------------------------------------------------------------------------------
GRAPH = """
name: interop-demo
nodes:
  - id: sig
    plugin: basic.signal
ros2:
  domain_id: 7
  publish: {sig/out: /hand/signal}
"""


def _session(listen=(), connect=()):
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("listen/endpoints", json.dumps(list(listen)))
    conf.insert_json5("connect/endpoints", json.dumps(list(connect)))
    return zenoh.open(conf)


def _wait(pred, timeout=5.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.02)
    return False


def _tokens(session, selector):
    """Liveliness tokens visible from ``session`` (what rmw_zenoh's graph cache reads)."""
    found: set[str] = set()
    for _ in range(50):
        found = {str(r.ok.key_expr) for r in session.liveliness().get(selector) if r.ok is not None}
        if any("/MP/" in t or "/MS/" in t for t in found):
            break
        time.sleep(0.05)
    return found


def test_graph_option_is_validated(tmp_path):
    bad = GRAPH.replace("{sig/out: /hand/signal}", "{sig/nope: /hand/signal, ghost/out: /x, sig/out: bad-name}")
    graph, problems = read_graph_text(bad, tmp_path / "g.yaml")
    text = "\n".join(p.message for p in problems)
    assert graph is None
    assert "'sig/nope' is not an output" in text and "no node 'ghost'" in text and "'bad-name' is not valid" in text


def test_graph_option_republishes_with_rmw_zenoh_key_attachment_and_tokens(tmp_path):
    graph, problems = read_graph_text(GRAPH, tmp_path / "g.yaml")
    assert not problems
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    hub, ros_side = _session(listen=[endpoint]), _session(connect=[endpoint])
    got = []
    key = rz.data_key(7, "/hand/signal", "handflow_msgs/msg/Array", type_hash("handflow_msgs/msg/Array"))
    sub = ros_side.declare_subscriber(key, lambda s: got.append((s.payload.to_bytes(), s.attachment.to_bytes())))
    bridge = Ros2Bridge(hub, graph)
    try:
        tokens = _tokens(ros_side, "@ros2_lv/7/**")
        zid = str(hub.zid())
        assert any(t.startswith(f"@ros2_lv/7/{zid}/") and "/NN/%/%/interop_demo" in t for t in tokens)
        pub_tokens = [t for t in tokens if "/MP/" in t]
        assert pub_tokens == [bridge.publishers["sig/out"].token_key]
        assert pub_tokens[0].endswith(
            f"/interop_demo/%hand%signal/handflow_msgs::msg::dds_::Array_/{key.rsplit('/', 1)[1]}/::,10:,:,:,,"
        )
        msg = Array(data=np.array([1.5, -2.0]))
        msg.header = Header("sig", 41, 2_000_000_007)
        payload, att = wire.pack(msg)
        pub = ros_side.declare_publisher("handflow/interop-demo/sig/out")
        assert _wait(lambda: (pub.put(payload, attachment=att), bool(got))[1])
        body, ros_att = got[0]
        assert body == payload  # the CDR is forwarded unchanged
        seq, stamp, gid = rz.parse_attachment(ros_att)
        assert seq >= 1 and abs(stamp - time.time_ns()) < 5e9 and gid == bridge.publishers["sig/out"].gid
    finally:
        sub.undeclare()
        bridge.close()
        ros_side.close()
        hub.close()


def test_each_launcher_publishes_the_topics_of_its_host(tmp_path):
    text = GRAPH.replace("    plugin: basic.signal", "    plugin: basic.signal\n    host: lab")
    graph, problems = read_graph_text(text, tmp_path / "g.yaml")
    assert not problems
    session = _session()
    try:
        here, there = Ros2Bridge(session, graph), Ros2Bridge(session, graph, "lab")
        assert not here.publishers and list(there.publishers) == ["sig/out"]
        here.close()
        there.close()
    finally:
        session.close()


def test_joint_state_cdr_of_the_option_is_what_rosbags_writes(store):
    msg = JointState(names=["a", "b"], positions=np.array([0.1, 0.2]), hand="human", handedness="left")
    msg.header = Header("x", 1, 3_000_000_004)
    payload, _ = wire.pack(msg)
    ros = store.deserialize_cdr(payload, "sensor_msgs/msg/JointState")
    assert ros.name == ["a", "b"] and ros.header.frame_id == "human/left" and ros.header.stamp.nanosec == 4
    assert bytes(store.serialize_cdr(ros, "sensor_msgs/msg/JointState")) == payload
