"""``camera.opencv`` on real MJPG video files written with OpenCV's ``VideoWriter`` (docs/camera.md).

The frames a graph records must be exactly what OpenCV decodes from the same file (MJPG is lossy,
so the reference is the decoded file, not the frames written), converted to RGB, in order; the
recording replays with the same frames.
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.graphs.model import GraphError, load_graph
from handflow.plugins.camera.synthetic import frame_counter, write_counter_video
from handflow.plugins.camera.video import CameraError, DropCounter, VideoSource, check_video
from tests.conftest import REPO, handflow

FRAMES, W, H, FPS = 40, 160, 120, 20.0


@pytest.fixture
def video(tmp_path):
    return write_counter_video(tmp_path / "counter.avi", FRAMES, W, H, FPS)


def decoded_rgb(path) -> list[np.ndarray]:
    """Every frame OpenCV decodes from ``path``, as RGB."""
    cap, frames = cv2.VideoCapture(str(path)), []
    while (got := cap.read())[0]:
        frames.append(cv2.cvtColor(got[1], cv2.COLOR_BGR2RGB))
    cap.release()
    return frames


def graph_file(tmp_path, name: str, nodes: list[dict], **extra) -> str:
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump({"name": name, **extra, "nodes": nodes}))
    return str(path)


# ---------------------------------------------------------------------------------------------
# the reader, without the runtime
# ---------------------------------------------------------------------------------------------
def test_reader_gives_the_decoded_frames_as_rgb_in_order_then_ends(video):
    reference = decoded_rgb(video)
    assert len(reference) == FRAMES
    with VideoSource(video) as source:
        assert source.fps == FPS and source.mode == (W, H, FPS)
        frames = list(source)
        assert source.ended and source.read() is None
    assert [f.index for f in frames] == list(range(FRAMES))
    assert [frame_counter(f.rgb) for f in frames] == list(range(FRAMES))
    for f, ref in zip(frames, reference):
        assert f.rgb.shape == (H, W, 3) and np.array_equal(f.rgb, ref)
    stamps = [f.stamp_ns for f in frames]
    assert stamps == sorted(stamps) and source.drops.dropped == 0


def test_reader_loops_and_resizes(video):
    with VideoSource(video, width=80, height=60, loop=True) as source:
        frames = [source.read() for _ in range(FRAMES + 5)]
    assert all(f.rgb.shape == (60, 80, 3) for f in frames)
    assert [f.index for f in frames] == list(range(FRAMES + 5))  # indices go on across the loop
    bgr = cv2.cvtColor(decoded_rgb(video)[0], cv2.COLOR_RGB2BGR)
    first = cv2.cvtColor(cv2.resize(bgr, (80, 60), interpolation=cv2.INTER_AREA), cv2.COLOR_BGR2RGB)
    assert np.array_equal(frames[0].rgb, first) and np.array_equal(frames[FRAMES].rgb, first)


def test_drop_counter_counts_the_frames_missing_between_device_times():
    drops = DropCounter(fps=30.0)
    for ms in (0.0, 33.3, 66.7, 166.7, 200.0, 300.0):  # 2 missing after 66.7, 2 after 200
        drops.note(ms)
    assert drops.dropped == 4
    drops.restart()
    drops.note(0.0)  # a looped file starts again: no drop
    assert drops.dropped == 4


def test_unreadable_file_and_missing_camera_say_what_to_do(tmp_path):
    bad = tmp_path / "broken.avi"
    bad.write_bytes(b"RIFF" + bytes(200))
    with pytest.raises(CameraError, match="OpenCV cannot read it.*ffmpeg"):
        check_video(bad)
    free = next(i for i in range(10, 64) if not Path(f"/dev/video{i}").exists())
    with pytest.raises(CameraError, match=f"no camera at device index {free}.*plug the webcam in"):
        VideoSource(free)


# ---------------------------------------------------------------------------------------------
# preflight: handflow validate / run refuse a graph whose camera cannot work
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("broken.avi", "OpenCV cannot read it"),
        ("nowhere.avi", "camera or video file nowhere.avi: no such file or folder"),
        pytest.param(
            37,
            "camera or video file /dev/video37: no such file or folder",
            marks=pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/dev/videoN exists on Linux only"),
        ),
    ],
)
def test_preflight_names_the_bad_source_and_what_to_do(tmp_path, source, expected):
    (tmp_path / "broken.avi").write_bytes(b"not a video")
    path = graph_file(tmp_path, "cam", [{"id": "cam", "plugin": "camera.opencv", "params": {"source": source}}])
    with pytest.raises(GraphError, match=expected) as err:
        load_graph(path, preflight=True)
    assert "set 'source'" in str(err.value) or "ffmpeg" in str(err.value)
    proc = handflow("validate", path)
    assert proc.returncode == 2 and expected in proc.stdout + proc.stderr and "Traceback" not in proc.stderr


def test_width_without_height_is_refused(tmp_path, video):
    path = graph_file(
        tmp_path, "cam", [{"id": "cam", "plugin": "camera.opencv", "params": {"source": str(video), "width": 64}}]
    )
    with pytest.raises(GraphError, match="give both 'width' and 'height'"):
        load_graph(path)


# ---------------------------------------------------------------------------------------------
# a graph: recorded, replayed, compared
# ---------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_video_file_streams_into_a_recording_that_replays_with_the_same_frames(tmp_path, video):
    live = graph_file(
        tmp_path,
        "camlive",
        [
            {"id": "cam", "plugin": "camera.opencv", "params": {"source": video.name}},
            {"id": "jpeg", "plugin": "basic.compress_image", "inputs": {"image": "cam/image"}},
        ],
    )
    rec, rep = tmp_path / "live.mcap", tmp_path / "replayed.mcap"
    handflow("run", live, "--duration", "5", "--record", str(rec), check=True, timeout=120)

    messages = list(iter_recording(rec))
    images = [rm.decode() for rm in messages if rm.topic.endswith("/cam/image")]
    assert len(images) == FRAMES, f"recorded {len(images)} of {FRAMES} frames"
    for i, (msg, ref) in enumerate(zip(images, decoded_rgb(video))):
        assert msg.encoding == "rgb8" and msg.header.seq == i + 1
        assert np.array_equal(msg.to_array(), ref), f"frame {i} differs from the decoded file"
    gaps = np.diff([m.header.stamp_ns for m in images]) / 1e9
    assert 0.5 / FPS < np.median(gaps) < 2 / FPS  # plays at the file's frame rate
    statuses = [rm.decode() for rm in messages if rm.topic.endswith("/cam/status")]
    assert statuses[-1].state == "end"
    assert statuses[-1].counters["frames"] == FRAMES and statuses[-1].counters["dropped"] == 0
    assert sum(rm.topic.endswith("/jpeg/compressed") for rm in messages) == FRAMES

    replay_graph = graph_file(
        tmp_path,
        "camreplay",
        [{"id": "jpeg", "plugin": "basic.compress_image", "inputs": {"image": "cam/image"}}],
        external={"cam/image": "Image"},
    )
    handflow("replay", str(rec), "--into", replay_graph, "--lockstep", "--record", str(rep), check=True, timeout=120)
    replayed = [rm.decode() for rm in iter_recording(rep) if rm.topic.endswith("/cam/image")]
    assert len(replayed) == FRAMES
    assert all(np.array_equal(a.to_array(), b.to_array()) for a, b in zip(images, replayed))
    # exit 0: every image and JPEG equal, none only on one side
    handflow("compare", str(rec), str(rep), "--topics", "cam/image", "jpeg/compressed", check=True)


@pytest.mark.slow
def test_demo_webcam_with_a_video_file_records_the_camera(tmp_path, video):
    """The flagship plus the camera, its source a video file (a graph variant next to the shipped one)."""
    shutil.copytree(REPO / "configs", tmp_path / "configs", ignore=shutil.ignore_patterns("__pycache__"))
    spec = yaml.safe_load((REPO / "configs" / "demo_webcam.yaml").read_text())
    webcam = next(n for n in spec["nodes"] if n["plugin"] == "camera.opencv")
    webcam["params"].update(source=str(video), loop=True)
    variant = tmp_path / "configs" / "demo_video.yaml"  # beside the flagship's models, which it names
    variant.write_text(yaml.safe_dump(spec))
    rec = tmp_path / "demo_webcam.mcap"
    handflow("run", str(variant), "--duration", "5", "--record", str(rec), check=True, timeout=240, cwd=tmp_path)
    proc = handflow("inspect", str(rec), "--json", check=True)
    counts = {t["topic"].split("/", 2)[2]: t["count"] for t in json.loads(proc.stdout)["topics"]}
    assert counts.get(f"{webcam['id']}/image", 0) >= 4 * FPS, counts
    assert counts.get("webcam_jpeg/compressed", 0) > 0 and counts.get("glove/frames", 0) > 0, counts


def test_demo_webcam_is_the_flagship_plus_the_camera():
    """configs/demo_webcam.yaml stays the flagship (configs/demo.yaml) with the camera and its JPEG added."""
    demo = yaml.safe_load((REPO / "configs" / "demo.yaml").read_text())
    webcam = yaml.safe_load((REPO / "configs" / "demo_webcam.yaml").read_text())
    added = [n for n in webcam["nodes"] if n not in demo["nodes"]]
    assert [n["plugin"] for n in added] == ["camera.opencv", "basic.compress_image"]
    assert added[1]["inputs"] == {"image": f"{added[0]['id']}/image"}
    assert [n for n in webcam["nodes"] if n not in added] == demo["nodes"]
    assert {k: v for k, v in webcam.items() if k not in ("name", "description", "nodes", "record")} == {
        k: v for k, v in demo.items() if k not in ("name", "description", "nodes", "record")
    }
    load_graph(REPO / "configs" / "demo_webcam.yaml")
