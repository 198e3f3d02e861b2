"""Node ``tracker.color_blobs``: :class:`~handflow.plugins.tracker.blobs.BallTracker` on the runtime.

Input ``image`` (Image, rgb8/rgba8).  Outputs per image: ``balls`` (Points2D, normalised so mark A
is (−1, 0) and mark B (1, 0); unordered, with track ids; invalid when not seen or when a mark is
missing) and ``marks`` (Points2D, raw pixel centroids of mark A and mark B, ids 0 and 1).
"""

from __future__ import annotations

from pydantic import Field

from handflow.framework.files.params import StrictModel
from handflow.framework.messages import Image, MessageError, Points2D
from handflow.framework.plugin import Node

from .blobs import BALL_HSV, MARK_A_HSV, MARK_B_HSV, BallTracker, HSVRange


def _range(values: list[int]) -> HSVRange:
    return HSVRange(tuple(values[:3]), tuple(values[3:]))  # type: ignore[arg-type]


class TrackerParams(StrictModel):
    """HSV bounds as [h_lo, s_lo, v_lo, h_hi, s_hi, v_hi] (OpenCV scale; h_lo > h_hi wraps the hue)."""

    ball_hsv: list[int] = Field(default_factory=lambda: [*BALL_HSV.lower, *BALL_HSV.upper], min_length=6, max_length=6)
    mark_a_hsv: list[int] = Field(
        default_factory=lambda: [*MARK_A_HSV.lower, *MARK_A_HSV.upper], min_length=6, max_length=6
    )
    mark_b_hsv: list[int] = Field(
        default_factory=lambda: [*MARK_B_HSV.lower, *MARK_B_HSV.upper], min_length=6, max_length=6
    )
    min_area: float = Field(12.0, gt=0, description="smallest ball blob in px")
    max_jump: float = Field(60.0, gt=0, description="largest frame-to-frame ball motion in px kept on one track id")


class ColorBlobTrackerNode(Node):
    """Colour-blob tracker: two identical balls (normalised to the wrist marks) and the two marks."""

    Params = TrackerParams
    inputs = {"image": Image}
    outputs = {"balls": Points2D, "marks": Points2D}

    def setup(self) -> None:
        prm = self.params
        self.tracker = BallTracker(
            ball_hsv=_range(prm.ball_hsv),
            mark_a_hsv=_range(prm.mark_a_hsv),
            mark_b_hsv=_range(prm.mark_b_hsv),
            min_area=prm.min_area,
            max_jump=prm.max_jump,
        )

    def on_message(self, port: str, msg: Image) -> None:
        if msg.encoding not in ("rgb8", "rgba8"):
            raise MessageError(f"tracker.color_blobs needs rgb8 or rgba8 images, got encoding '{msg.encoding}'")
        rgb = msg.to_array()[:, :, :3]
        res = self.tracker.update(rgb)
        stamp = msg.header.stamp_ns or None
        self.ctx.publish("balls", Points2D(points=res.balls, valid=res.balls_valid, ids=res.ids), stamp_ns=stamp)
        self.ctx.publish("marks", Points2D(points=res.marks_px, valid=res.marks_valid, ids=[0, 1]), stamp_ns=stamp)
