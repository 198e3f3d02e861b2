"""The flagship graph headless (real processes, Zenoh, pybullet, MCAP) and replay determinism."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from handflow.framework.recording import read_messages
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
]


@pytest.fixture(scope="module")
def flagship(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("flagship")
    rec = tmp / "demo.mcap"
    handflow("run", "configs/demo.yaml", "--duration", "16", "--record", str(rec), timeout=120, check=True)
    by_topic: dict[str, list] = {}
    for topic, msg, log_ns in read_messages(rec):
        by_topic.setdefault(topic.split("/", 2)[2], []).append((msg, log_ns))
    return tmp, rec, by_topic


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
