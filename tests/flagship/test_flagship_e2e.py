"""The flagship graph headless (real processes, Zenoh, pybullet, MCAP) and replay determinism."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import yaml

from handflow.framework.commands.inspect import summarize
from handflow.framework.files.mcap_reader import read_messages
from handflow.plugins.demo.gestures import GestureScript
from tests.conftest import REPO, handflow

pytestmark = pytest.mark.slow

EXPECTED = [
    "glove/frames",
    "glove/status",
    "human/joints",
    "shadow/joints",
    "takeover/out",
    "controller/targets",
    "sim/joints",
    "sim/contacts",
    "sim/scene",
    "sim/image",
    "segmenter/labels",
    "segmenter/events",
    "sim/tf",
    "sim/markers",
    "sim/description",
    "human_tf/tf",
    "human_tf/description",
    "gesture/markers",
    "camera/compressed",
]


@pytest.fixture(scope="module")
def flagship(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("flagship")
    rec = tmp / "demo.mcap"
    proc = handflow("run", "configs/demo.yaml", "--duration", "16", "--record", str(rec), timeout=120, check=True)
    (tmp / "stderr.txt").write_text(proc.stderr)
    by_topic: dict[str, list] = {}
    for topic, msg, log_ns in read_messages(rec):
        by_topic.setdefault(topic.split("/", 2)[2], []).append((msg, log_ns))
    return tmp, rec, by_topic


def test_a_normal_run_logs_no_warning_and_shows_the_recognised_gesture(flagship):
    """docs/flagship.md, "What you see": the status line names the gestures of the script's first
    16 s (grasp, then wave from 8 s), and nothing of a normal start is a WARNING."""
    log = (flagship[0] / "stderr.txt").read_text()
    assert not [line for line in log.splitlines() if "WARNING" in line or "Traceback" in line], log
    shown = re.findall(r"\[handflow\.status\] segmenter/labels: (\w+)", log)
    assert {"grasp", "wave"} <= set(shown), log
    assert shown.index("grasp") < len(shown) - 1 - shown[::-1].index("wave")  # in the script's order


def test_inspect_rates_the_labels_as_their_joint_stream(flagship):
    """One label per joint message: `handflow inspect` gives both the glove's 50 Hz (docs/recording.md)."""
    rates = {t["topic"].split("/", 2)[2]: t["rate_hz"] for t in summarize(str(flagship[1]))["topics"]}
    assert rates["segmenter/labels"] == pytest.approx(rates["shadow/joints"], rel=0.01)
    assert rates["shadow/joints"] == pytest.approx(50.0, rel=0.02)


def test_flagship_records_every_stream(flagship):
    _, _, topics = flagship
    missing = [t for t in EXPECTED if not topics.get(t)]
    assert not missing, f"no messages on {missing}; got {sorted(topics)}"
    # the segmenter saw every joint message from the first one on, labels keep the observation's stamp
    joint_stamps = [m.header.stamp_ns for m, _ in topics["shadow/joints"]]
    labels = [m for m, _ in topics["segmenter/labels"]]
    assert [m.index for m in labels] == list(range(len(labels)))
    assert [m.header.stamp_ns for m in labels] == joint_stamps[: len(labels)]
    assert len(labels) >= len(joint_stamps) - 2
    # the mapping chain keeps the glove frame's stamp
    frame_stamps = [m.header.stamp_ns for m, _ in topics["glove/frames"]]
    assert joint_stamps == frame_stamps[: len(joint_stamps)]


def test_flagship_recognises_the_scripted_gestures(flagship):
    _, _, topics = flagship
    labels = [m.label for m, _ in topics["segmenter/labels"]]
    truth = GestureScript().labels(np.arange(len(labels)) / 50.0)  # glove at 50 Hz, no frame lost
    settled = slice(50, None)  # after the first second
    agree = np.mean(np.array(labels[settled]) == np.array(truth[settled]))
    assert agree > 0.7, f"{agree:.2f} of the labels match the script"


def test_lockstep_replay_into_the_segmenter_reproduces_the_labels(flagship):
    tmp, rec, topics = flagship
    graph = yaml.safe_load((REPO / "configs" / "demo_segment_only.yaml").read_text())
    for node in graph["nodes"]:
        if node["id"] == "segmenter":
            node["params"]["models"] = str(REPO / "configs" / "models" / "gestures")
        if node["id"] == "labels":
            node["params"]["jsonl"] = str(tmp / "replayed.jsonl")
    (tmp / "segment_only.yaml").write_text(yaml.safe_dump(graph))
    handflow("replay", str(rec), "--into", str(tmp / "segment_only.yaml"), "--lockstep", timeout=180, check=True)
    replayed = [json.loads(line)["msg"] for line in (tmp / "replayed.jsonl").read_text().splitlines()]
    live = [m for m, _ in topics["segmenter/labels"]]
    assert len(replayed) >= len(live) > 100
    for a, b in zip(live, replayed):
        assert (a.index, a.label, a.header.stamp_ns) == (b["index"], b["label"], b["header"]["stamp_ns"])
        np.testing.assert_array_equal(a.scores, b["scores"])


def test_a_ros_2_reader_finds_the_3d_view_in_the_recording(flagship):
    """rosbags (an independent reader) sees TF trees matching the recorded URDFs, markers, label text, JPEGs."""
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    from handflow.framework.ros2.types import decode_cdr
    from tests.simulator.test_viewer import assert_tree_matches_urdf

    _, rec, _ = flagship
    last: dict[str, object] = {}
    with AnyReader([rec], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        assert all(c.topic.startswith("/handflow/demo/") for c in reader.connections)  # ROS 2 names
        types = {c.topic.split("/", 3)[3]: c.msgtype for c in reader.connections}
        for conn, _, raw in reader.messages():
            last[conn.topic.split("/", 3)[3]] = (reader.deserialize(raw, conn.msgtype), raw, conn.msgtype)
    assert types["sim/tf"] == types["human_tf/tf"] == "tf2_msgs/msg/TFMessage"
    assert types["sim/markers"] == types["gesture/markers"] == "visualization_msgs/msg/MarkerArray"
    assert types["sim/description"] == "std_msgs/msg/String"
    assert types["camera/compressed"] == "sensor_msgs/msg/CompressedImage"
    for hand in ("sim", "human_tf"):
        tf = decode_cdr(bytes(last[f"{hand}/tf"][1]), "tf2_msgs/msg/TFMessage")
        assert_tree_matches_urdf(tf, last[f"{hand}/description"][0].data)
    assert {m.type for m in last["sim/markers"][0].markers} == {3}  # bottle and cap cylinders
    (text,) = last["gesture/markers"][0].markers
    assert text.type == 9 and text.text.split()[0] in {"grasp", "wave", "pinch", "turn", "unknown"}
    assert bytes(last["camera/compressed"][0].data[:2]) == b"\xff\xd8"  # JPEG
    with open(rec, "rb") as f:
        names = {a.name for a in make_reader(f).iter_attachments()}
    assert {"handflow/demo/sim/description.urdf", "handflow/demo/human_tf/description.urdf"} <= names
