"""Message schemas and the codec: round trips, and the publisher rejects NaN/inf and bad shapes."""

from __future__ import annotations

import re

import numpy as np
import pytest

from handflow.framework.messages import (
    Array,
    Contacts,
    GloveFrame,
    Image,
    JointState,
    Label,
    LatentState,
    MessageError,
    Points2D,
    SegmentEvent,
    Status,
    decode,
    encode,
    json_schema,
    message_types,
)
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.basic.transform import GainOffset

SAMPLES = [
    Array(data=np.arange(6.0).reshape(2, 3), names=list("abcdef")),
    JointState(names=["a", "b"], positions=[0.1, -0.2], velocities=[0.0, 1.0], hand="shadow"),
    GloveFrame(sensors=list(range(22)), device_time=123, status=1, arrival_ns=99),
    Contacts(segments=["ffdistal"], bodies=["cap"], forces=[1.5]),
    Points2D(points=[[0.5, 0.1], [np.nan, np.nan]], valid=[True, False], ids=[3, 4]),
    Image.from_array(np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3)),
    LatentState(manifold="cap", coords=[1.0, 0.3], error=0.01),
    Label(label="A", index=4, classes=["A", "B"], scores=[0.9, -0.2]),
    SegmentEvent(kind="revision", label="B", start_index=3, end_index=9, previous_label="A"),
    Status(state="connected", counters={"corrupt": 2.0}, text="ok"),
]


@pytest.mark.parametrize("msg", SAMPLES, ids=lambda m: type(m).__name__)
def test_round_trip(msg):
    msg.check()
    back = decode(encode(msg))
    assert type(back) is type(msg)
    for name, value in vars(msg).items():
        other = getattr(back, name)
        if isinstance(value, np.ndarray):
            assert np.array_equal(value, other, equal_nan=value.dtype.kind == "f")
        else:
            assert value == other


def test_every_type_has_a_json_schema():
    for cls in message_types().values():
        schema = json_schema(cls)
        assert schema["title"] == cls.TYPE and "header" in schema["properties"]


@pytest.mark.parametrize(
    "bad, needle",
    [
        (JointState(names=["a"], positions=[np.nan]), "NaN/inf"),
        (JointState(names=["a", "b"], positions=[0.0]), "joint names"),
        (Array(data=[1.0, np.inf]), "NaN/inf"),
        (Points2D(points=[[np.nan, 0.0]], valid=[True]), "valid point"),
        (GloveFrame(sensors=[300]), "0..255"),
        (Image(width=2, height=2, step=6, data=b"\x00" * 5), "needs 12 bytes"),
    ],
)
def test_check_rejects(bad, needle):
    with pytest.raises(MessageError, match=needle):
        bad.check()


def test_publisher_names_node_and_port():
    h = NodeHarness(GainOffset, {"gain": np.inf}, node_id="scale").setup()
    h.send("in", Array(data=[1.0, 2.0]))  # the runtime drops the input whose output cannot be published
    ((port, reason),) = h.dropped
    assert port == "in" and re.search("node 'scale' port 'out'.*NaN/inf", reason)


def test_decode_garbage_is_a_clear_error():
    with pytest.raises(MessageError, match="cannot decode"):
        decode(b"\x00\x01garbage")
    with pytest.raises(MessageError):
        decode(b'{"type": "handflow.Nope"}')
