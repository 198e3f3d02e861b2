"""``basic.signal``: the same values as Array or as JointState, checked against the port type."""

from __future__ import annotations

import numpy as np
import pytest

from handflow.framework.messages import Array, JointState
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.basic.signal import SignalSource


@pytest.mark.parametrize("message, kind", [("array", Array), ("joint_state", JointState)])
def test_signal_publishes_the_declared_type(message, kind):
    h = NodeHarness(SignalSource, {"kind": "noise", "width": 24, "seed": 3, "message": message}).setup()
    h.tick()
    h.tick()
    out = h.published["out"]
    assert [type(m) for m in out] == [kind, kind]
    assert SignalSource.output_types(SignalSource.Params(message=message))["out"] is kind
    values = [m.positions if message == "joint_state" else m.data for m in out]
    expected = np.random.default_rng(3).standard_normal((2, 24))
    np.testing.assert_allclose(values, expected)
    if message == "joint_state":
        assert out[0].names == [f"j{k}" for k in range(24)]


def test_joint_state_names_come_from_the_csv_header(tmp_path):
    (tmp_path / "j.csv").write_text("WRJ1,WRJ2\n0.1,0.2\n0.3,0.4\n")
    h = NodeHarness(SignalSource, {"kind": "csv", "csv": "j.csv", "message": "joint_state"}, base_dir=tmp_path).setup()
    h.tick()
    (msg,) = h.published["out"]
    assert msg.names == ["WRJ1", "WRJ2"] and msg.positions.tolist() == [0.1, 0.2]
