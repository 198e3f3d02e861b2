"""What docs/recording.md says a file holds, checked on real recordings, as ROS 2 tools read them
(``rosbags``); recordings made before the ROS 2 names (the shipped ones) still read and replay."""

from __future__ import annotations

import re

import pytest
from mcap.reader import make_reader

from handflow.framework.files.mcap_reader import read_messages
from tests.framework._rec_helpers import REPO, chain, handflow, read_jsonl, unique, write_graph

PAGE = (REPO / "docs" / "recording.md").read_text()
OLD_STYLE = sorted((REPO / "recordings").glob("*.mcap"))


@pytest.fixture(autouse=True)
def private_run_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))


def _said(pattern: str) -> str:
    m = re.search(pattern, PAGE)
    assert m, f"docs/recording.md no longer says {pattern!r}"
    return m.group(1)


@pytest.mark.slow
def test_a_recording_is_what_the_page_says_and_what_ros_2_tools_read(tmp_path):
    rosbags = pytest.importorskip("rosbags.highlevel")
    typesys = pytest.importorskip("rosbags.typesys")
    name = unique("fmt")
    path = tmp_path / "run.mcap"
    res = handflow("run", str(chain(tmp_path / "g.yaml", name)), "--duration", "1", "--record", str(path))
    assert res.returncode == 0, res.stderr
    with open(path, "rb") as f:
        reader = make_reader(f)
        profile = reader.get_header().profile
        summary = reader.get_summary()
    channels = sorted(c.topic for c in summary.channels.values())
    assert profile == _said(r"profile `(\w+)`")
    assert {c.message_encoding for c in summary.channels.values()} == {_said(r"message encoding `(\w+)`")}
    assert {s.encoding for s in summary.schemas.values()} == {_said(r"schema encoding `(\w+)`")}
    template = _said(r"named with the ROS 2 name of its Zenoh key:\s+`([^`]+)`")
    assert channels == [
        template.replace("<graph>", name).replace("<node>/<port>", t) for t in ("scale/out", "source/out")
    ]
    assert "foxglove_image" not in PAGE and not any(c.endswith("foxglove_image") for c in channels)
    assert {s.name for s in summary.schemas.values()} == {"handflow_msgs/msg/Array"}
    store = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    with rosbags.AnyReader([path], default_typestore=store) as r:  # as `ros2 bag` would
        assert sorted(c.topic for c in r.connections) == channels
        decoded = [(c.topic, r.deserialize(raw, c.msgtype)) for c, _, raw in r.messages()]
    ours = list(read_messages(path))  # handflow names topics by their Zenoh key
    assert [(t, list(m.data)) for t, m in decoded] == [("/" + t, list(m.data)) for t, m, _ in ours]
    assert len(ours) > 50


@pytest.mark.parametrize("path", OLD_STYLE, ids=[p.name for p in OLD_STYLE])
def test_the_shipped_old_style_recordings_still_read(path):
    with open(path, "rb") as f:
        assert not any(c.topic.startswith("/") for c in make_reader(f).get_summary().channels.values())
    topics = {t for t, _, _ in read_messages(path)}
    assert topics and all(t.startswith("handflow/") for t in topics)
    assert {t for t, _, _ in read_messages(path, ["/" + next(iter(topics))])} == {next(iter(topics))}


@pytest.mark.slow
def test_an_old_style_recording_replays_and_rerecords_with_ros_2_names(tmp_path):
    old = REPO / "recordings" / "ball_swap_demo.mcap"
    name = unique("oldrep")
    graph = write_graph(
        tmp_path / "g.yaml",
        name,
        "external: {sim/joints: JointState}\n"
        "nodes:\n  - id: sink\n    plugin: basic.sink\n    params: {jsonl: joints.jsonl}\n    inputs: {in: sim/joints}\n",
    )
    out = tmp_path / "again.mcap"
    res = handflow("replay", str(old), "--into", str(graph), "--speed", "8", "--record", str(out), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert len(read_jsonl(tmp_path / "joints.jsonl")) == 384
    with open(out, "rb") as f:
        assert {c.topic for c in make_reader(f).get_summary().channels.values()} == {f"/handflow/{name}/sim/joints"}
    same = handflow("compare", str(old), str(out), "--topics", "sim/joints")
    assert same.returncode == 0, same.stdout + same.stderr
