"""``basic.select``: forward one of two JointState streams — how a controller takes over a hand.

``use`` names the stream forwarded at start (``primary`` or ``secondary``); with
``switch_after_s`` set, the node switches to the *other* stream that many seconds after the first
message it receives (on either input), once, and logs it.  Messages of the stream not in use are
dropped.  The forwarded message keeps its stamp, so latency stays measurable end to end.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from handflow.framework.files.params import StrictModel
from handflow.framework.messages import JointState
from handflow.framework.plugin import Node

INPUTS = ("primary", "secondary")


class SelectParams(StrictModel):
    use: Literal["primary", "secondary"] = Field("primary", description="input forwarded at start")
    switch_after_s: float | None = Field(
        None, gt=0, description="switch to the other input this many seconds after the first message; null = never"
    )


class Select(Node):
    """Forward 'primary' or 'secondary' to 'out'; optionally switch once after switch_after_s."""

    Params = SelectParams
    inputs = {"primary": JointState, "secondary": JointState}
    outputs = {"out": JointState}

    def setup(self) -> None:
        self.active = self.params.use
        self.first_ns: int | None = None
        self.switched = False

    def _maybe_switch(self, now_ns: int) -> None:
        after = self.params.switch_after_s
        if self.first_ns is None:
            self.first_ns = now_ns
        if after is None or self.switched or now_ns - self.first_ns < after * 1e9:
            return
        self.switched = True
        self.active = INPUTS[1 - INPUTS.index(self.active)]
        self.ctx.log.info("after %.1f s: now forwarding '%s'", after, self.active)

    def on_message(self, port: str, msg: JointState) -> None:
        self._maybe_switch(self.ctx.now_ns())
        if port == self.active:
            self.ctx.publish("out", msg, stamp_ns=msg.header.stamp_ns)
