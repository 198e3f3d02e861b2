"""lsl.inlet / lsl.outlet on loopback with liblsl (mne-lsl), clock offsets applied (docs/lsl.md)."""

from __future__ import annotations

import sys
import time
import uuid

import numpy as np
import pytest
from pydantic import ValidationError

from handflow.framework.files.inputs import missing_modules
from handflow.framework.messages import Array, MessageError
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.lsl.clock import lsl_to_stamps, stamp_to_lsl, wall_minus_lsl_ns
from handflow.plugins.lsl.nodes import InletParams, LslInlet, LslOutlet

lsl = pytest.importorskip("mne_lsl.lsl")


def _wait(pred, timeout=5.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.02)
    return False


def test_clock_mapping_round_trips_and_uses_the_wall_offset():
    offset = wall_minus_lsl_ns(lsl.local_clock)
    assert abs(lsl.local_clock() * 1e9 + offset - time.time_ns()) < 5e6
    stamps = lsl_to_stamps(np.array([1.5, 2.25]), 10)
    assert stamps.tolist() == [1_500_000_010, 2_250_000_010]
    assert stamp_to_lsl(1_500_000_010, 10) == 1.5


def test_inlet_publishes_samples_with_sender_stamps_mapped_to_wall_time():
    sid = f"hf-{uuid.uuid4().hex[:8]}"
    info = lsl.StreamInfo("emg", "EMG", 3, 100.0, "float32", sid)
    info.set_channel_names(["flexor", "extensor", "thumb"])
    outlet = lsl.StreamOutlet(info)
    h = NodeHarness(LslInlet, {"source_id": sid, "resolve_timeout_s": 5})
    h.setup()
    try:
        past = lsl.local_clock() - 5.0  # samples taken 5 s ago by the sender's clock
        expected_wall = time.time_ns() - 5_000_000_000
        outlet.push_sample(np.array([np.nan, 0, 0], np.float32), timestamp=past - 0.01)  # dropped
        for i in range(20):
            outlet.push_sample(np.array([i, 2 * i, -i], np.float32), timestamp=past + i / 100)
        assert _wait(lambda: (h.tick(), len(h.published["out"]) >= 20)[1])
        assert len(h.published["out"]) == 20
        msgs = h.published["out"]
        assert msgs[0].names == ["flexor", "extensor", "thumb"]
        assert [m.data.tolist() for m in msgs[:3]] == [[0, 0, 0], [1, 2, -1], [2, 4, -2]]
        assert abs(msgs[0].header.stamp_ns - expected_wall) < 50_000_000  # clock-corrected, not arrival time
        assert msgs[19].header.stamp_ns - msgs[0].header.stamp_ns == pytest.approx(190_000_000, abs=1_000_000)
    finally:
        h.teardown()


def test_outlet_sends_arrays_that_an_lsl_inlet_reads_with_their_stamps():
    sid = f"hf-{uuid.uuid4().hex[:8]}"
    h = NodeHarness(LslOutlet, {"name": "hand", "type": "Mocap", "source_id": sid, "channels": 2})
    h.setup()
    try:
        found = lsl.resolve_streams(timeout=5, source_id=sid)
        inlet = lsl.StreamInlet(found[0])
        inlet.open_stream(timeout=5)
        stamp = time.time_ns() - 2_000_000_000
        got: list = []

        def pull():
            h.send("in", Array(data=np.array([0.5, -1.0])), stamp_ns=stamp)
            data, ts = inlet.pull_chunk(timeout=0.1)
            got.extend(zip(np.asarray(data).tolist(), list(ts)))
            return bool(got)

        assert _wait(pull)
        values, ts = got[0]
        assert values == [0.5, -1.0]
        assert abs(ts * 1e9 + wall_minus_lsl_ns(lsl.local_clock) - stamp) < 5_000_000
        h.send("in", Array(data=np.ones(3)))
        assert "has 2 channels, got 3 values" in h.dropped[-1][1]
        inlet.close_stream()
    finally:
        h.teardown()


def test_inlet_without_a_stream_fails_setup_with_what_it_looked_for():
    h = NodeHarness(LslInlet, {"name": f"absent-{uuid.uuid4().hex[:6]}", "resolve_timeout_s": 0.3})
    with pytest.raises(RuntimeError, match="no LSL stream with {'name': 'absent-"):
        h.setup()


def test_params_need_a_filter_and_the_plugins_name_the_extra_when_missing(monkeypatch):
    with pytest.raises(ValidationError, match="give at least one of name, type, source_id"):
        InletParams()
    assert missing_modules(LslInlet.requires) == missing_modules(LslOutlet.requires) == []
    monkeypatch.setitem(sys.modules, "mne_lsl", None)  # as if mne-lsl were not installed
    assert missing_modules(LslInlet.requires) == [
        "needs mne_lsl, which is not installed: install it with pip install 'handflow[lsl]'"
    ]
    assert issubclass(MessageError, ValueError)
