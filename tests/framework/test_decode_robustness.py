"""Property tests: any payload decodes to a valid message or raises MessageError (docs/robustness.md).

Mutated real payloads (every message type; shipped recordings' messages), structurally random JSON
with a known type name, and random bytes.  ``benchmarks/decode_fuzz.py`` runs 100 000 of them.
"""

from __future__ import annotations

import json
from itertools import islice
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.messages import GloveFrame, Message, MessageError, decode, encode, message_types
from handflow.framework.testkit.fuzzing import EXTREMES, OPS, Mutation, malformed_payloads, mutate, sample_messages
from handflow.recordings import __file__ as _recordings_init

SAMPLES = {type(m).TYPE: encode(m) for m in sample_messages()}
RECORDINGS = sorted(Path(_recordings_init).parent.glob("*.mcap"))


def _recorded_payloads(per_topic: int = 3) -> list[bytes]:
    out: list[bytes] = []
    for path in RECORDINGS:
        seen: dict[str, int] = {}
        for rm in iter_recording(path):
            if seen.get(rm.topic, 0) < per_topic:
                seen[rm.topic] = seen.get(rm.topic, 0) + 1
                out.append(rm.data)
    return out


RECORDED = _recorded_payloads()

mutations = st.lists(
    st.builds(Mutation, st.sampled_from(OPS), st.floats(0, 1, exclude_max=True), st.integers(0, 2**16)),
    min_size=1,
    max_size=4,
)
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def assert_valid_or_rejected(payload: bytes) -> Message | None:
    """The property: a checked message that survives its own round trip, or MessageError."""
    try:
        msg = decode(payload)
    except MessageError:
        return None
    msg.check()  # decode returned only a publishable message
    again = decode(encode(msg))
    assert type(again) is type(msg) and again.header == msg.header
    return msg


def test_the_samples_cover_every_message_type():
    assert set(SAMPLES) == set(message_types())
    assert {json.loads(p)["type"] for p in RECORDED} >= {"handflow.GloveFrame", "handflow.JointState"}


@pytest.mark.parametrize("type_name", sorted(SAMPLES))
@FUZZ
@given(ops=mutations)
def test_mutated_samples_of_every_type(type_name, ops):
    assert_valid_or_rejected(mutate(SAMPLES[type_name], ops))


@FUZZ
@given(index=st.integers(0, len(RECORDED) - 1), ops=mutations)
def test_mutated_recorded_payloads(index, ops):
    assert_valid_or_rejected(mutate(RECORDED[index], ops))


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8) | st.sampled_from(EXTREMES[:9]),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=8), inner, max_size=5),
    max_leaves=20,
)


@FUZZ
@given(type_name=st.sampled_from(sorted(SAMPLES)), data=st.data())
def test_random_fields_with_a_known_type(type_name, data):
    names = list(json.loads(SAMPLES[type_name]))
    doc = {"type": type_name}
    for name in data.draw(st.lists(st.sampled_from(names), unique=True)):
        doc[name] = data.draw(json_values)
    assert_valid_or_rejected(json.dumps(doc).encode())


@FUZZ
@given(st.binary(max_size=300))
def test_random_bytes(payload):
    assert_valid_or_rejected(payload)


def test_a_sample_of_the_benchmark_stream():
    """A seeded slice of what benchmarks/decode_fuzz.py runs (both outcomes occur)."""
    outcomes = [assert_valid_or_rejected(p) is not None for p in islice(malformed_payloads(3000, seed=7), 3000)]
    assert 0 < sum(outcomes) < len(outcomes)


@pytest.mark.parametrize(
    "payload, needle",
    [
        (b'{"type":"handflow.GloveFrame","sensors":[1e308,1e308]}', "int64 values"),
        (b'{"type":"handflow.GloveFrame","sensors":[300]}', "0..255"),
        (b'{"type":"handflow.JointState","names":["a"],"positions":[NaN]}', "NaN is not allowed"),
        (b'{"type":"handflow.JointState","names":["a"],"positions":[1e999]}', "NaN/inf"),
        (b'{"type":"handflow.JointState","names":["a","b"],"positions":[0.1]}', "joint names"),
        (b'{"type":"handflow.JointState","names":"ab","positions":[0.1]}', "'names' must be a list"),
        (b'{"type":"handflow.GloveFrame","sensors":[[1],[2,3]]}', "not a regular array"),
        (b'{"type":"handflow.GloveFrame","sensors":[1.5]}', "int64 values"),
        (b'{"type":"handflow.GloveFrame","sensors":[1],"device_time":18446744073709551617}', "int64 integer"),
        (b'{"type":"handflow.Array","data":[1.0,2.0],"shape":[-1,-2]}', "shape"),
        (b'{"type":"handflow.Image","width":4,"height":1,"encoding":"rgb8","step":4,"data":"AAAAAA=="}', "step"),
        (b'{"type":"handflow.Image","data":"not base64!"}', "base64"),
        (b'{"type":"handflow.Status","counters":{"a":"x"}}', "must be a number"),
        (b'{"type":"handflow.Label","header":{"seq":-4}}', "seq"),
        (b'{"type":"handflow.Nope"}', "unknown message type"),
        (b"[1,2]", "JSON object"),
        (b"\xff\xfe", "cannot decode"),
        (b"[" * 100_000, "cannot decode"),
    ],
)
def test_rejections_say_what_is_wrong(payload, needle):
    with pytest.raises(MessageError, match=needle):
        decode(payload)


def test_extreme_but_valid_values_decode():
    frame = GloveFrame(sensors=np.full(22, 255), device_time=2**63 - 1, status=0, arrival_ns=-(2**63))
    back = decode(encode(frame))
    assert back.sensors.dtype == np.int64 and back.device_time == 2**63 - 1
