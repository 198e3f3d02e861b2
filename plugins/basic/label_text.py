"""Node ``basic.label_text``: a recognised label as a text marker for 3D viewers (docs/foxglove.md)."""

from __future__ import annotations

from pydantic import Field

from handflow.framework.files.params import StrictModel
from handflow.framework.messages import Label, Markers
from handflow.framework.plugin import Node


class LabelTextParams(StrictModel):
    """Parameters of ``basic.label_text``."""

    frame_id: str = Field("world", description="TF frame the text is placed in")
    position: tuple[float, float, float] = Field((0.0, 0.0, 0.5), description="text position in frame_id (m)")
    height: float = Field(0.04, gt=0, description="text height (m)")
    colour: tuple[float, float, float, float] = Field((1.0, 1.0, 1.0, 1.0), description="RGBA in 0..1")
    show_score: bool = Field(True, description="append the label's score when the message has scores")
    max_hz: float = Field(10.0, gt=0, description="at most this many markers per second (the latest label wins)")


class LabelText(Node):
    """Label in; one text marker out (namespace ``label``, id 0: each replaces the last; at most ``max_hz``)."""

    Params = LabelTextParams
    inputs = {"label": Label}
    outputs = {"markers": Markers}

    def setup(self) -> None:
        self.last_ns: int | None = None

    def on_message(self, port: str, msg: Label) -> None:
        prm = self.params
        now = self.ctx.now_ns()
        if self.last_ns is not None and now - self.last_ns < 1e9 / prm.max_hz - 1e3:  # 1 µs slack
            return
        self.last_ns = now
        text = msg.label
        if prm.show_score and msg.label in msg.classes and msg.scores.size:
            text = f"{text} ({msg.scores[msg.classes.index(msg.label)]:.2f})"
        marker = Markers(
            kinds=["text"],
            frame_ids=[prm.frame_id],
            namespaces=["label"],
            ids=[0],
            positions=[prm.position],
            orientations=[[0.0, 0.0, 0.0, 1.0]],
            scales=[[prm.height, prm.height, prm.height]],
            colours=[prm.colour],
            texts=[text],
        )
        self.ctx.publish("markers", marker, stamp_ns=msg.header.stamp_ns)
