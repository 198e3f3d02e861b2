"""Element-wise gain and offset on Array messages."""

from __future__ import annotations

from handflow.framework.files.params import StrictModel, live
from handflow.framework.messages import Array
from handflow.framework.plugin import Node


class GainOffsetParams(StrictModel):
    gain: float = live(1.0, description="factor applied to every value")
    offset: float = live(0.0, description="added after the gain")


class GainOffset(Node):
    """out = gain · in + offset (keeps the input's stamp, so latency is measured end to end)."""

    Params = GainOffsetParams
    inputs = {"in": Array}
    outputs = {"out": Array}

    def on_message(self, port: str, msg: Array) -> None:
        out = Array(data=msg.data * self.params.gain + self.params.offset, shape=list(msg.shape), names=msg.names)
        self.ctx.publish("out", out, stamp_ns=msg.header.stamp_ns)
