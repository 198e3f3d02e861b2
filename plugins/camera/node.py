"""``camera.opencv``: webcam or video file as ``Image`` messages (thin wrapper of
:class:`~handflow.plugins.camera.video.VideoSource`; docs/camera.md).

Every tick reads one frame and publishes it on ``image`` as ``rgb8`` (stamp = capture time: when
OpenCV returned the frame).  A video file plays at its own frame rate (or ``fps``), every frame in
order; at its end the node publishes an ``end`` status and nothing more (``loop: true`` starts
over).  A device is read at twice ``fps`` (default 30); each read waits for the device's next
frame.  ``status`` carries the counters ``frames``, ``dropped`` (frames the device delivered but
the node never read) and ``failed_reads`` every ``status_period_s`` and when the state changes.
For Foxglove, compress the images with ``basic.compress_image`` in the graph.
"""

from __future__ import annotations

import sys
from typing import Annotated

from pydantic import BeforeValidator, Field, model_validator

from handflow.framework.files.inputs import InputPath
from handflow.framework.files.params import StrictModel
from handflow.framework.messages import Image, Status
from handflow.framework.plugin import Node

from .video import VideoSource, check_video

DEVICE_RATE_FACTOR = 2.0  # device reads per frame period: a read waits for the device, so this only sets the ceiling


def _device_path(value):
    """A device index as its Linux device file (so preflight finds a missing webcam); other values unchanged."""
    if isinstance(value, int) and not isinstance(value, bool):
        return f"/dev/video{value}" if sys.platform.startswith("linux") else str(value)
    return value


SOURCE = InputPath(
    "any",
    "camera or video file",
    "plug the webcam in and set 'source' to its index (0 is /dev/video0; `ls /dev/video*` lists them), "
    "or set 'source' to a video file (relative to the graph file's folder)",
    check=check_video,
    skip=str.isdigit,  # a device index where there are no device files (not Linux): checked when opened
)


class OpenCVCameraParams(StrictModel):
    """Parameters of ``camera.opencv``."""

    source: Annotated[str, BeforeValidator(_device_path), SOURCE] = Field(
        "/dev/video0", description="device index (0 = first webcam), /dev/videoN, or a video file"
    )
    width: int | None = Field(None, ge=1, description="frame width (with height): asked of a device, frames resized")
    height: int | None = Field(None, ge=1, description="frame height (with width)")
    fps: float | None = Field(None, gt=0, description="frames per second; default: a file's own rate, a device's 30")
    loop: bool = Field(False, description="a video file starts over at its end (else the node stops publishing)")
    frame_id: str = "camera"
    status_period_s: float = Field(1.0, gt=0, description="status is published at least this often")

    @model_validator(mode="after")
    def _both_sizes(self):
        if (self.width is None) != (self.height is None):
            raise ValueError("give both 'width' and 'height', or neither (the source's own size)")
        return self


class OpenCVCamera(Node):
    """Webcam or video file → RGB Image (stamp = capture time) + status with frame/drop counters."""

    Params = OpenCVCameraParams
    outputs = {"image": Image, "status": Status}

    def _source(self) -> int | str:
        src = self.params.source
        return int(src) if src.isdigit() else str(self.ctx.resolve_path(src))

    def tick_rate_hz(self) -> float:
        p = self.params
        if p.source.isdigit() or p.source.startswith("/dev/"):
            return DEVICE_RATE_FACTOR * (p.fps or 30.0)
        if p.fps:
            return p.fps
        with VideoSource(self._source()) as probe:  # the node is ticked before setup opens the file
            return probe.fps

    def setup(self) -> None:
        p = self.params
        self.video = VideoSource(self._source(), p.width, p.height, p.fps, p.loop, clock_ns=self.ctx.now_ns)
        w, h, fps = self.video.mode
        self.ctx.log.info("camera %s: %d×%d at %.4g fps", p.source, w, h, fps)
        if self.video.is_device and p.width and (w, h) != (p.width, p.height):
            self.ctx.log.warning(
                "camera %s delivers %d×%d; frames are resized to %d×%d", p.source, w, h, p.width, p.height
            )
        self._state, self._last_status_ns = None, None

    def tick(self) -> None:
        frame = self.video.read()
        if frame is not None:
            self.ctx.publish("image", Image.from_array(frame.rgb, self.params.frame_id), stamp_ns=frame.stamp_ns)
        state = "end" if self.video.ended else ("warn" if frame is None else "ok")
        now = self.ctx.now_ns()
        if state != self._state or now - self._last_status_ns >= self.params.status_period_s * 1e9:
            if state == "end" and self._state != "end":
                self.ctx.log.info(
                    "end of %s after %d frames; publishing nothing more (loop: true plays it again)",
                    self.params.source,
                    self.video.frames,
                )
            self.ctx.publish("status", self.status(state))
            self._state, self._last_status_ns = state, now

    def status(self, state: str) -> Status:
        v = self.video
        counters = {"frames": v.frames, "dropped": v.drops.dropped, "failed_reads": v.failed_reads, "fps": v.fps}
        return Status(state=state, counters=counters, text=str(self.params.source))

    def teardown(self) -> None:
        video = getattr(self, "video", None)
        if video is not None:
            video.close()
