"""Forwarding a received message unchanged re-sends its CDR body (framework/runtime/forwarding.py, docs/ros2.md)."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from handflow.framework import keys, wire
from handflow.framework.graphs.model import load_graph
from handflow.framework.messages import Header, JointState, Status
from handflow.framework.network import sessions as transport
from handflow.framework.network.settings import ZenohSettings
from handflow.framework.recorder.replay import wait_matching
from handflow.framework.ros2.types import encode_cdr, restamped_cdr
from handflow.framework.runtime import forwarding
from handflow.framework.runtime.runner import GroupRuntime
from handflow.framework.testkit.fuzzing import sample_messages
from tests.framework._rec_helpers import unique, write_graph

STAMP = 1_700_000_000_123_456_789


def _received(msg):
    payload, att = wire.pack(msg)
    return wire.unpack(payload, att), payload


def _joint_state(names, positions, stamp=STAMP):
    msg = JointState(names=list(names), positions=np.asarray(positions, dtype=float), hand="shadow")
    msg.header = Header("source", 3, stamp)
    return msg


@pytest.mark.parametrize("msg", sample_messages(), ids=lambda m: m.TYPE)
def test_every_type_repacks_to_the_bytes_a_fresh_encoding_gives(msg):
    got, body = _received(msg)
    snap = forwarding.snapshot(got)
    got.header = Header("forwarder", 9, STAMP + 5_000_000_017)
    repacked = wire.repack(got, body)
    if snap is None or repacked is None:  # encoded again: nothing to compare
        return
    assert forwarding.unchanged(got, snap)
    assert repacked == wire.pack(got)


@pytest.mark.parametrize("msg", sample_messages(), ids=lambda m: m.TYPE)
def test_a_reused_body_never_depends_on_the_source_node(msg):
    """Types whose body holds more of the header than the stamp (Status: the source) must not be reused."""
    msg.header = Header("a", 1, STAMP)
    body = encode_cdr(msg)
    if restamped_cdr(body, msg.TYPE, STAMP) is None:
        return
    msg.header = Header("another_node", 2, STAMP)
    assert encode_cdr(msg) == body


def test_status_and_headerless_types_are_always_encoded_again():
    status = Status(state="ok", counters={"a": 1.0})
    status.header = Header("n", 1, STAMP)
    assert restamped_cdr(encode_cdr(status), Status.TYPE, STAMP) is None


@settings(max_examples=60, deadline=None)
@given(
    names=st.lists(st.text(min_size=1, max_size=8), min_size=0, max_size=12),
    stamp=st.integers(0, 2**31 * 10**9 - 1),
)
def test_joint_states_repack_for_any_names_and_stamp(names, stamp):
    got, body = _received(_joint_state(names, np.arange(len(names)) * 0.5))
    snap = forwarding.snapshot(got)
    assert snap is not None and forwarding.unchanged(got, snap)
    got.header = Header("sel", 4, stamp)
    assert wire.repack(got, body) == wire.pack(got)


@pytest.mark.parametrize(
    "edit",
    [
        lambda m: m.names.append("extra"),
        lambda m: m.names.__setitem__(0, "renamed"),
        lambda m: setattr(m, "positions", m.positions * 2),
        lambda m: setattr(m, "hand", "human"),
        lambda m: setattr(m, "names", ("j0", "j1")),
    ],
    ids=["append", "rename", "new_array", "new_hand", "tuple_names"],
)
def test_any_edit_after_decoding_is_seen(edit):
    got, _ = _received(_joint_state(["j0", "j1"], [0.1, 0.2]))
    snap = forwarding.snapshot(got)
    edit(got)
    assert not forwarding.unchanged(got, snap)


def test_arrays_that_can_be_written_get_no_snapshot():
    msg = _joint_state(["j0"], [0.1])  # built in this process: its array is writeable
    assert forwarding.snapshot(msg) is None
    got, _ = _received(msg)
    with pytest.raises(ValueError):
        got.positions.flags.writeable = True  # a view of the received bytes stays read-only


def test_the_runtime_forwards_the_received_body_and_encodes_edited_messages(tmp_path):
    """A real runtime and Zenoh session: basic.select republishes the very bytes it received; a
    message the node changed (here: by the test, between decoding and publishing) is encoded anew."""
    name = unique("fwd")
    graph = load_graph(
        write_graph(
            tmp_path / "g.yaml",
            name,
            """nodes:
  - id: source
    plugin: basic.signal
    params: {kind: noise, rate_hz: 10, width: 3, message: joint_state}
  - id: sel
    plugin: basic.select
    inputs: {primary: source/out}
""",
        )
    )
    hub_ep = transport.hub_endpoint_for()
    hub = transport.open_hub(ZenohSettings(), hub_ep)
    rt = GroupRuntime(graph, ["sel"], hub_ep, lockstep=False)
    got: list[bytes] = []
    arrived = threading.Event()

    def on(sample):
        got.append(wire.sample_parts(sample)[0])
        arrived.set()

    sub = hub.declare_subscriber(keys.topic_key(name, "sel", "out"), on)
    rt.slots[0].node.setup()
    try:
        assert wait_matching([rt.slots[0].ctx._pubs["out"].zenoh], 10)
        msg = _joint_state([f"j{i}" for i in range(24)], np.linspace(-1, 1, 24))
        payload, att = wire.pack(msg)
        payload += b"\0\0\0"  # trailing padding a reader accepts and a fresh encoding does not write
        rt._deliver(rt.slots[0], "primary", payload, att)
        assert arrived.wait(10)
        assert got[0] == payload  # select keeps the stamp: the very body was sent again

        original = rt.slots[0].node.on_message

        def edit_then_forward(port, m):
            m.names[0] = "edited"
            original(port, m)

        rt.slots[0].node.on_message = edit_then_forward
        arrived.clear()
        rt._deliver(rt.slots[0], "primary", payload, att)
        assert arrived.wait(10)
        edited = wire.unpack(got[1], att)
        assert edited.names[0] == "edited" and edited.names[1:] == msg.names[1:]
        assert got[1] == wire.pack(edited)[0]  # encoded anew
    finally:
        sub.undeclare()
        if rt.local:
            rt.local.close()
        rt.session.close()
        hub.close()
