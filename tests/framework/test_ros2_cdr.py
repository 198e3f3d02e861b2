"""handflow messages as ROS 2 CDR: bytes and schemas checked against rosbags (an independent implementation)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from handflow.framework.messages import Image, JointState, Markers, Message, MessageError, Status, Text, Transforms
from handflow.framework.ros2 import cdr
from handflow.framework.ros2.types import decode_cdr, encode_cdr, own_msgs, ros_type, schema_text
from handflow.framework.testkit.fuzzing import BYTE_OPS, Mutation, mutate, sample_messages

typesys = pytest.importorskip("rosbags.typesys")

SAMPLES = sample_messages()


@pytest.fixture(scope="module")
def store():
    ts = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    types = {}
    for name, text in own_msgs().items():
        types.update(typesys.get_types_from_msg(text, name))
    ts.register(types)
    return ts


def _same(a: Message, b: Message) -> None:
    assert type(a) is type(b) and a.header == b.header
    for name, value in vars(a).items():
        other = getattr(b, name)
        if isinstance(value, np.ndarray):
            assert np.array_equal(value, other, equal_nan=value.dtype.kind == "f") and value.dtype == other.dtype
        else:
            assert value == other, name


@pytest.mark.parametrize("msg", SAMPLES, ids=lambda m: m.TYPE)
def test_bytes_and_schema_match_rosbags(store, msg):
    data = encode_cdr(msg)
    ros = ros_type(msg.TYPE)
    theirs = store.deserialize_cdr(data, ros)  # rosbags reads our bytes ...
    assert bytes(store.serialize_cdr(theirs, ros)) == data  # ... and writes the very same bytes
    assert store.generate_msgdef(ros, ros_version=2)[0] == schema_text(msg.TYPE)
    headers = (
        [theirs.header]
        if hasattr(theirs, "header")
        else [m.header for m in vars(theirs).get("transforms", vars(theirs).get("markers", []))]
    )
    assert [h.stamp.sec * 10**9 + h.stamp.nanosec for h in headers] == [msg.header.stamp_ns] * len(headers)
    back = decode_cdr(data, msg.TYPE, msg.header.source, msg.header.seq)
    if isinstance(msg, Text):  # std_msgs/String has no header: the stamp is not carried
        back.header.stamp_ns = msg.header.stamp_ns
    _same(back, msg)


def test_standard_types_carry_their_fields(store):
    js = next(m for m in SAMPLES if isinstance(m, JointState))
    ros = store.deserialize_cdr(encode_cdr(js), "sensor_msgs/msg/JointState")
    assert ros.name == js.names and np.array_equal(ros.position, js.positions) and ros.header.frame_id == "shadow/right"
    img = next(m for m in SAMPLES if isinstance(m, Image))
    ros = store.deserialize_cdr(encode_cdr(img), "sensor_msgs/msg/Image")
    assert (ros.width, ros.height, ros.encoding, ros.step) == (img.width, img.height, "rgb8", img.step)
    assert ros.data.tobytes() == img.data
    status = next(m for m in SAMPLES if isinstance(m, Status))
    ros = store.deserialize_cdr(encode_cdr(status), "diagnostic_msgs/msg/DiagnosticArray")
    (s,) = ros.status
    assert (s.level, s.name, s.message, s.values[0].key, float(s.values[0].value)) == (
        0,
        "connected",
        "ok",
        "corrupt",
        2.0,
    )


def test_a_joint_state_from_another_ros_system_decodes(store):
    Time, Header = store.types["builtin_interfaces/msg/Time"], store.types["std_msgs/msg/Header"]
    JS = store.types["sensor_msgs/msg/JointState"]
    ros = JS(Header(Time(12, 5), "base_link"), ["a", "b"], np.array([0.1, 0.2]), np.array([]), np.array([]))
    msg = decode_cdr(store.serialize_cdr(ros, "sensor_msgs/msg/JointState"), "sensor_msgs/msg/JointState", "ros", 4)
    assert msg.names == ["a", "b"] and msg.hand == "base_link" and msg.header.stamp_ns == 12 * 10**9 + 5
    assert (msg.header.source, msg.header.seq) == ("ros", 4)


def test_arrays_are_views_of_the_payload():
    img = Image.from_array(np.zeros((480, 640, 3), np.uint8))
    js = JointState(names=[f"j{i}" for i in range(24)], positions=np.linspace(0, 1, 24))
    back = decode_cdr(encode_cdr(js), js.TYPE)
    assert back.positions.base is not None and not back.positions.flags.owndata
    assert decode_cdr(encode_cdr(img), img.TYPE).to_array().shape == (480, 640, 3)


names_lists = st.lists(st.text(max_size=6), max_size=4)


@settings(max_examples=200, deadline=None)
@given(st.lists(names_lists, min_size=1, max_size=8), st.data())
def test_remembered_name_lists_read_and_write_as_the_bytes_say(lists, data):
    """Name lists repeat per topic and are remembered (framework/ros2/cdr.py); a stream of lists
    of equal and different lengths, some repeated, decodes to its own names and the same bytes."""
    for names in [data.draw(st.sampled_from(lists)) for _ in range(12)]:
        js = JointState(names=names, positions=np.arange(len(names), dtype=float))
        payload = encode_cdr(js)
        cdr._ENCODED_NAMES.clear()
        assert encode_cdr(js) == payload  # the remembered bytes are the freshly encoded ones
        back = decode_cdr(payload, js.TYPE)
        assert back.names == names
        back.names.append("x")  # a receiver's list is its own
        assert decode_cdr(payload, js.TYPE).names == names
    for cut in range(len(payload)):  # the last list is remembered: every cut of its bytes is still refused
        with pytest.raises(MessageError):
            decode_cdr(payload[:cut], js.TYPE)


@pytest.mark.parametrize(
    "data, needle",
    [
        (b"\x00", "encapsulation header"),
        (b"\x00\x00\x00\x00" + bytes(16), "little-endian"),
        (encode_cdr(JointState(names=["a"], positions=[1.0]))[:-3], "truncated"),
        (encode_cdr(JointState(names=["a"], positions=[1.0])) + bytes(8), "unexpected byte"),
        (encode_cdr(JointState(names=["a"], positions=[1.0])).replace(b"\xf0\x3f", b"\xf0\x7f"), "NaN/inf"),
    ],
)
def test_malformed_cdr_is_rejected_with_a_reason(data, needle):
    with pytest.raises(MessageError, match=needle):
        decode_cdr(data, "handflow.JointState")


@settings(max_examples=300, deadline=None)
@given(
    index=st.integers(0, len(SAMPLES) - 1),
    ops=st.lists(
        st.builds(Mutation, st.sampled_from(BYTE_OPS), st.floats(0, 1, exclude_max=True), st.integers(0, 2**16)),
        min_size=1,
        max_size=4,
    ),
)
def test_mutated_cdr_decodes_or_raises_message_error(index, ops):
    msg = SAMPLES[index]
    try:
        back = decode_cdr(mutate(encode_cdr(msg), ops), msg.TYPE)
    except MessageError:
        return
    back.check()
    decode_cdr(encode_cdr(back), msg.TYPE)


@settings(max_examples=200, deadline=None)
@given(type_index=st.integers(0, len(SAMPLES) - 1), data=st.binary(max_size=200))
def test_random_cdr_bytes_decode_or_raise_message_error(type_index, data):
    try:
        decode_cdr(b"\x00\x01\x00\x00" + data, SAMPLES[type_index].TYPE).check()
    except MessageError:
        pass


def test_view_types_carry_their_fields(store):
    tf = next(m for m in SAMPLES if isinstance(m, Transforms))
    ros = store.deserialize_cdr(encode_cdr(tf), "tf2_msgs/msg/TFMessage")
    assert [t.header.frame_id for t in ros.transforms] == tf.parents
    assert [t.child_frame_id for t in ros.transforms] == tf.children
    r = ros.transforms[1].transform.rotation
    assert [r.x, r.y, r.z, r.w] == tf.rotations[1].tolist()
    markers = next(m for m in SAMPLES if isinstance(m, Markers))
    ros = store.deserialize_cdr(encode_cdr(markers), "visualization_msgs/msg/MarkerArray")
    assert [m.type for m in ros.markers] == [2, 9] and ros.markers[1].text == "grasp"
    assert ros.markers[0].scale.x == 0.04 and ros.markers[0].color.g == np.float32(0.2)
    text = next(m for m in SAMPLES if isinstance(m, Text))
    assert store.deserialize_cdr(encode_cdr(text), "std_msgs/msg/String").data == text.data


def test_markers_from_another_ros_system_that_handflow_cannot_carry_are_rejected(store):
    markers = next(m for m in SAMPLES if isinstance(m, Markers))
    ros = store.deserialize_cdr(encode_cdr(markers), "visualization_msgs/msg/MarkerArray")
    Point = store.types["geometry_msgs/msg/Point"]
    ros.markers[0].points = [Point(0.0, 0.0, 0.0)]
    with pytest.raises(MessageError, match="no points"):
        decode_cdr(store.serialize_cdr(ros, "visualization_msgs/msg/MarkerArray"), "visualization_msgs/msg/MarkerArray")
    ros.markers[0].points, ros.markers[0].type = [], 10  # a mesh
    with pytest.raises(MessageError, match="type 10"):
        decode_cdr(store.serialize_cdr(ros, "visualization_msgs/msg/MarkerArray"), "visualization_msgs/msg/MarkerArray")


def test_transforms_need_unit_quaternions_and_one_entry_per_frame():
    with pytest.raises(MessageError, match="unit quaternions"):
        Transforms(parents=["a"], children=["b"], translations=[[0, 0, 0]], rotations=[[0, 0, 0, 2.0]]).check()
    with pytest.raises(MessageError, match="one entry per transform"):
        Transforms(parents=["a", "b"], children=["b"], translations=[[0, 0, 0]], rotations=[[0, 0, 0, 1.0]]).check()


def test_the_wire_peeks_the_stamp_of_headerless_types():
    from handflow.framework import wire

    for msg in (m for m in SAMPLES if isinstance(m, (Transforms, Markers))):
        payload, att = wire.pack(msg)
        assert wire.peek(payload, att).stamp_ns == msg.header.stamp_ns
    empty = Transforms()
    empty.header.stamp_ns = 99
    assert wire.peek(*wire.pack(empty)).stamp_ns == 0  # an empty TFMessage carries no stamp


@pytest.mark.parametrize(
    "ros",
    [
        "tf2_msgs/msg/TFMessage",
        "visualization_msgs/msg/MarkerArray",
        "sensor_msgs/msg/CompressedImage",
        "std_msgs/msg/String",
    ],
)
def test_view_types_have_the_rihs01_hash_of_rosbags(store, ros):
    from handflow.framework.ros2.types import type_hash

    assert type_hash(ros) == store.hash_rihs01(ros)
