"""Element-wise gain and offset on Array messages."""

from __future__ import annotations

from handflow.framework.files.params import StrictModel
from handflow.framework.messages import Array
from handflow.framework.plugin import Node


class GainOffsetParams(StrictModel):
    gain: float = 1.0
    offset: float = 0.0


class GainOffset(Node):
    """out = gain · in + offset (keeps the input's stamp, so latency is measured end to end)."""

    Params = GainOffsetParams
    inputs = {"in": Array}
    outputs = {"out": Array}

    def on_message(self, port: str, msg: Array) -> None:
        out = Array(data=msg.data * self.params.gain + self.params.offset, shape=list(msg.shape), names=msg.names)
        self.ctx.publish("out", out, stamp_ns=msg.header.stamp_ns)
