"""Node ``basic.compress_image``: camera images as JPEG or PNG (``sensor_msgs/CompressedImage``, docs/foxglove.md)."""

from __future__ import annotations

from typing import Literal

import cv2
from pydantic import Field

from handflow.framework.files.params import StrictModel
from handflow.framework.messages import CompressedImage, Image, MessageError
from handflow.framework.plugin import Node

_TO_BGR = {"rgb8": cv2.COLOR_RGB2BGR, "rgba8": cv2.COLOR_RGBA2BGR, "bgra8": cv2.COLOR_BGRA2BGR}


def compress(image: Image, fmt: str = "jpeg", quality: int = 90) -> CompressedImage:
    """The image encoded by OpenCV as ``jpeg`` (``quality`` 0–100) or lossless ``png``."""
    if image.encoding not in ("mono8", "bgr8", *_TO_BGR):
        raise MessageError(f"cannot compress {image.encoding} images; use mono8, rgb8, bgr8, rgba8 or bgra8")
    if image.width == 0 or image.height == 0:
        raise MessageError(f"cannot compress an empty {image.width}×{image.height} image")
    pixels = image.to_array()
    if image.encoding in _TO_BGR:
        pixels = cv2.cvtColor(pixels, _TO_BGR[image.encoding])
    flags = [cv2.IMWRITE_JPEG_QUALITY, quality] if fmt == "jpeg" else []
    try:
        ok, data = cv2.imencode(".jpg" if fmt == "jpeg" else ".png", pixels, flags)
    except cv2.error as exc:  # e.g. larger than JPEG's 65535-pixel limit
        raise MessageError(f"OpenCV could not encode a {image.width}×{image.height} image as {fmt}: {exc}") from None
    if not ok:
        raise MessageError(f"OpenCV could not encode a {image.width}×{image.height} image as {fmt}")
    return CompressedImage(format=fmt, data=data.tobytes(), frame_id=image.frame_id)


class CompressImageParams(StrictModel):
    """Parameters of ``basic.compress_image``."""

    format: Literal["jpeg", "png"] = "jpeg"
    quality: int = Field(90, ge=0, le=100, description="JPEG quality")


class CompressImage(Node):
    """Image in; the same image as JPEG/PNG out (keeps the stamp)."""

    Params = CompressImageParams
    inputs = {"image": Image}
    outputs = {"compressed": CompressedImage}

    def on_message(self, port: str, msg: Image) -> None:
        out = compress(msg, self.params.format, self.params.quality)
        self.ctx.publish("compressed", out, stamp_ns=msg.header.stamp_ns)
