"""basic.label_text and basic.compress_image: what the 3D view and the image panel receive."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from handflow.framework.messages import Image, Label, MessageError
from handflow.framework.ros2.types import decode_cdr, encode_cdr
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.basic.compress_image import CompressImage, compress
from handflow.plugins.basic.label_text import LabelText


def test_label_text_replaces_one_text_marker_with_the_label_and_its_score():
    h = NodeHarness(LabelText, {"position": [0, 0, 0.4], "height": 0.05}).setup()
    h.send("label", Label(label="grasp", classes=["grasp", "wave"], scores=[0.87, 0.1]), stamp_ns=5)
    h.send("label", Label(label="wave"), stamp_ns=50_000_005)  # within 1 / max_hz (10 Hz): skipped
    h.send("label", Label(label="unknown"), stamp_ns=100_000_005)
    first, second = h.published["markers"]
    assert first.texts == ["grasp (0.87)"] and second.texts == ["unknown"]
    assert first.kinds == ["text"] and (first.namespaces, first.ids.tolist()) == (
        second.namespaces,
        second.ids.tolist(),
    )
    assert first.header.stamp_ns == 5 and first.scales[0, 2] == pytest.approx(0.05)
    back = decode_cdr(encode_cdr(first), first.TYPE)
    assert back.texts == first.texts and np.array_equal(back.positions, [[0, 0, 0.4]])


@pytest.mark.parametrize("encoding", ["rgb8", "rgba8", "mono8"])
def test_png_is_lossless_and_jpeg_close(encoding):
    rng = np.random.default_rng(0)
    channels = {"rgb8": 3, "rgba8": 4, "mono8": 1}[encoding]
    pixels = rng.integers(0, 256, (24, 32, channels), dtype=np.uint8).squeeze()
    if encoding == "rgba8":
        pixels[..., 3] = 255
    img = Image(width=32, height=24, encoding=encoding, step=32 * channels, data=pixels.tobytes(), frame_id="cam")
    png = compress(img, "png")
    decoded = cv2.imdecode(np.frombuffer(png.data, np.uint8), cv2.IMREAD_UNCHANGED)
    rgb = decoded if channels == 1 else cv2.cvtColor(decoded, cv2.COLOR_BGR2RGB)
    assert np.array_equal(rgb, pixels if channels != 4 else pixels[..., :3]) and png.frame_id == "cam"
    smooth = Image.from_array(np.tile(np.linspace(0, 255, 32, dtype=np.uint8)[None, :, None], (24, 1, 3)))
    jpeg = compress(smooth, "jpeg", 95)
    back = cv2.cvtColor(cv2.imdecode(np.frombuffer(jpeg.data, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    assert jpeg.format == "jpeg" and np.abs(back.astype(int) - smooth.to_array()).mean() < 3


def test_compress_node_keeps_the_stamp_and_rejects_unknown_encodings():
    h = NodeHarness(CompressImage, {"format": "png"}).setup()
    h.send("image", Image.from_array(np.zeros((8, 8, 3), np.uint8)), stamp_ns=42)
    (out,) = h.published["compressed"]
    assert out.header.stamp_ns == 42 and out.data.startswith(b"\x89PNG")
    h.send("image", Image(width=2, height=2, encoding="mono16", step=4, data=bytes(8)))
    assert "mono16" in h.dropped[0][1]
    with pytest.raises(MessageError):
        compress(Image(width=2, height=2, encoding="yuv422", step=4, data=bytes(8)))


@settings(max_examples=60, deadline=None)
@given(
    width=st.integers(0, 40),
    height=st.integers(0, 40),
    pad=st.integers(0, 5),
    encoding=st.sampled_from(["mono8", "rgb8", "bgr8", "rgba8", "bgra8", "mono16", "yuv422"]),
    fmt=st.sampled_from(["jpeg", "png"]),
)
def test_compress_node_never_crashes_on_a_valid_image(width, height, pad, encoding, fmt):
    channels = {"mono8": 1, "rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mono16": 2, "yuv422": 2}[encoding]
    step = width * channels + pad
    img = Image(
        width=width,
        height=height,
        encoding=encoding,
        step=step,
        data=bytes(range(256)) * (step * height // 256) + bytes(step * height % 256),
    )
    img.check()
    h = NodeHarness(CompressImage, {"format": fmt}).setup()
    h.send("image", img)
    assert len(h.published.get("compressed", [])) + len(h.dropped) == 1
