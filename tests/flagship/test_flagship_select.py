"""basic.select: which stream drives the hand, and the one-time takeover switch."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from handflow.framework.messages import JointState
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.basic.select import Select


def js(value: float) -> JointState:
    return JointState(names=["a"], positions=[value])


def test_forwards_only_the_stream_in_use_with_its_stamp():
    h = NodeHarness(Select, {}).setup()
    h.send("primary", js(1.0), stamp_ns=10)
    h.send("secondary", js(2.0), stamp_ns=20)
    h.send("primary", js(3.0), stamp_ns=30)
    out = h.published["out"]
    assert [m.positions[0] for m in out] == [1.0, 3.0]
    assert [m.header.stamp_ns for m in out] == [10, 30]


def test_use_secondary():
    h = NodeHarness(Select, {"use": "secondary"}).setup()
    h.send("primary", js(1.0), stamp_ns=1)
    h.send("secondary", js(2.0), stamp_ns=2)
    assert [m.positions[0] for m in h.published["out"]] == [2.0]


def test_switches_once_after_the_given_time():
    h = NodeHarness(Select, {"switch_after_s": 1.0}).setup()
    t0 = 5_000_000_000
    h.send("primary", js(1.0), stamp_ns=t0)  # the clock starts with the first message
    h.send("secondary", js(2.0), stamp_ns=t0 + 500_000_000)
    h.send("primary", js(3.0), stamp_ns=t0 + 999_000_000)
    h.send("primary", js(4.0), stamp_ns=t0 + 1_000_000_000)  # switched: the glove no longer drives
    h.send("secondary", js(5.0), stamp_ns=t0 + 1_100_000_000)
    h.send("secondary", js(6.0), stamp_ns=t0 + 9_000_000_000)
    assert [m.positions[0] for m in h.published["out"]] == [1.0, 3.0, 5.0, 6.0]
    assert h.node.active == "secondary"


@pytest.mark.parametrize("params", [{"use": "both"}, {"switch_after_s": 0}, {"switch_after": 3}])
def test_bad_params_are_rejected(params):
    with pytest.raises(ValidationError):
        Select.Params.model_validate(params)
