"""Frames from a webcam or a video file through OpenCV, as RGB arrays with capture times (docs/camera.md).

:class:`VideoSource` is the plain reader the ``camera.opencv`` node wraps; it needs no runtime::

    with VideoSource("clip.avi") as video:
        for frame in video:          # Frame(rgb, stamp_ns, index)
            ...

A source is a device index (``0``: the first webcam) or a path: a video file, or a device file
such as ``/dev/video0``.  Frames come as OpenCV decodes them, converted from OpenCV's BGR to RGB.
"""

from __future__ import annotations

import glob
import re
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

DEVICE_FILE = re.compile(r"/dev/video(\d+)$")


class CameraError(OSError):
    """A camera or video file that cannot be opened or read; the message says what to do."""


@dataclass(frozen=True)
class Frame:
    """One frame: ``rgb`` (height × width × 3, uint8), ``stamp_ns`` (capture time), ``index`` (0, 1, … per source)."""

    rgb: np.ndarray
    stamp_ns: int
    index: int


def video_devices() -> list[str]:
    """The video device files of this machine (Linux: ``/dev/video*``)."""
    return sorted(glob.glob("/dev/video*"))


def check_video(path: Path) -> None:
    """Raise :class:`CameraError` unless OpenCV opens ``path`` as a video and decodes its first frame
    (the preflight check of the node's ``source``)."""
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened() or not cap.read()[0]:
            raise CameraError(
                f"video file {path}: OpenCV cannot read it (not a video, damaged, or a codec this OpenCV "
                "lacks); convert it, e.g. `ffmpeg -i IN -c:v mjpeg -q:v 3 OUT.avi`, or choose another file"
            )
    finally:
        cap.release()


class DropCounter:
    """Frames lost between two captured frames, from the source's frame times (ms).

    A gap of more than 1.5 frame periods between consecutive frames counts ``round(gap / period) - 1``
    dropped frames (a webcam's driver overwrote frames the reader was too slow to take)."""

    def __init__(self, fps: float) -> None:
        self.period_ms = 1000.0 / fps if fps > 0 else 0.0
        self.dropped = 0
        self._last_ms: float | None = None

    def note(self, ms: float) -> None:
        if self.period_ms and self._last_ms is not None and ms - self._last_ms > 1.5 * self.period_ms:
            self.dropped += round((ms - self._last_ms) / self.period_ms) - 1
        self._last_ms = ms

    def restart(self) -> None:
        """The next frame starts a new sequence (a looped file)."""
        self._last_ms = None


class VideoSource:
    """A webcam (device index or ``/dev/videoN``) or a video file, read frame by frame.

    ``width``/``height``/``fps``: asked of a device (it may choose the nearest mode it has);
    frames of another size are resized to ``width`` × ``height``.  :attr:`fps` is the rate to read
    at: ``fps``, else the source's own rate (a file plays at its own frame rate), else 30.  ``loop``: a file starts over
    at its end; otherwise :meth:`read` returns None from then on.  ``clock_ns`` stamps each frame
    when OpenCV has it (default ``time.time_ns``).
    """

    def __init__(
        self,
        source: int | str | Path,
        width: int | None = None,
        height: int | None = None,
        fps: float | None = None,
        loop: bool = False,
        clock_ns: Callable[[], int] = time.time_ns,
    ) -> None:
        self.source = source
        self.size = (width, height) if width and height else None
        self.loop = loop
        self.clock_ns = clock_ns
        device = DEVICE_FILE.match(str(source)) if isinstance(source, (str, Path)) else None
        self.device: int | None = int(device.group(1)) if device else (source if isinstance(source, int) else None)
        self.frames = 0  # frames read
        self.failed_reads = 0  # a device's reads that returned no frame
        self.ended = False
        self._requested_fps = fps
        self._cap = self._open()
        native = self._cap.get(cv2.CAP_PROP_FPS)
        self.native_fps = float(native) if native and native > 0 else None
        self.fps = float(fps or self.native_fps or 30.0)
        self.drops = DropCounter(self.native_fps or self.fps)

    @property
    def is_device(self) -> bool:
        return self.device is not None

    def _open(self) -> cv2.VideoCapture:
        if self.is_device:
            cap = cv2.VideoCapture(self.device)
            if not cap.isOpened():
                found = ", ".join(video_devices()) or "none"
                raise CameraError(
                    f"camera {self.source}: no camera at device index {self.device} (video devices on this "
                    f"machine: {found}); plug the webcam in, set 'source' to its index (0 is /dev/video0), "
                    "or set 'source' to a video file"
                )
            if self.size:
                cap.set(cv2.CAP_PROP_FRAME_WIDTH, self.size[0])
                cap.set(cv2.CAP_PROP_FRAME_HEIGHT, self.size[1])
            if self._requested_fps:
                cap.set(cv2.CAP_PROP_FPS, self._requested_fps)
            return cap
        cap = cv2.VideoCapture(str(self.source))
        if not cap.isOpened():
            cap.release()
            raise CameraError(f"video file {self.source}: OpenCV cannot open it; check the path and the file")
        return cap

    @property
    def mode(self) -> tuple[int, int, float]:
        """(width, height, fps) the source delivers."""
        return (
            int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH)),
            int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT)),
            self.native_fps or 0.0,
        )

    def read(self) -> Frame | None:
        """The next frame, or None: at the end of a file (without ``loop``), or a device read that failed."""
        if self.ended:
            return None
        ok, bgr = self._cap.read()
        stamp = self.clock_ns()
        if not ok and not self.is_device and self.loop and self.frames:
            self._cap.release()
            self._cap = self._open()
            self.drops.restart()
            ok, bgr = self._cap.read()
            stamp = self.clock_ns()
        if not ok:
            if self.is_device:
                self.failed_reads += 1
            else:
                self.ended = True
            return None
        self.drops.note(self._cap.get(cv2.CAP_PROP_POS_MSEC))
        if self.size and (bgr.shape[1], bgr.shape[0]) != self.size:
            bgr = cv2.resize(bgr, self.size, interpolation=cv2.INTER_AREA)
        frame = Frame(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), stamp, self.frames)
        self.frames += 1
        return frame

    def __iter__(self) -> Iterator[Frame]:
        """Frames as fast as OpenCV reads them, until the end of a file (forever with ``loop``) or a
        device read that fails."""
        while (frame := self.read()) is not None:
            yield frame

    def close(self) -> None:
        self._cap.release()
        self.ended = True

    def __enter__(self) -> VideoSource:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
