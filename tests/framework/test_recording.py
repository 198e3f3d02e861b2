"""Recording helpers on real MCAP files: round trip, Foxglove channels, recovery, provenance, inspect."""

from __future__ import annotations

import argparse
import base64
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from handflow.framework.commands import inspect as inspect_cmd
from handflow.framework.files.mcap_reader import ReadReport, iter_recording, read_messages, read_report
from handflow.framework.files.mcap_writer import FOXGLOVE_IMAGE_SUFFIX, McapWriter, RecordingError, TopicFilter
from handflow.framework.graphs.model import load_graph
from handflow.framework.messages import Array, Header, Image, Label
from handflow.framework.recorder.graph_recorder import GraphRecorder
from handflow.framework.wire import peek_header

TOPIC = "handflow/g/src/out"


def _array(i: int) -> Array:
    msg = Array(data=np.array([i, i * 0.5, -i], dtype=float))
    msg.header = Header("src", i + 1, 1_000_000 + i)
    return msg


def _write(path, n=200, chunk_size=256 * 1024):
    with McapWriter(path, chunk_size=chunk_size, flush_interval_s=None) as w:
        for i in range(n):
            w.write(TOPIC, _array(i), log_time_ns=10_000_000 * i)
    return path


def test_round_trip_keeps_values_times_and_json_schemas(tmp_path):
    path = tmp_path / "a.mcap"
    img = Image.from_array(np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3))
    img.header = Header("cam", 7, 2_500_000_123)
    with McapWriter(path, encoding="json") as w:  # the earlier JSON dialect stays writable and readable
        for i in range(5):
            w.write(TOPIC, _array(i), log_time_ns=100 + i)
        w.write("handflow/g/cam/image", img, log_time_ns=200)
        w.write("handflow/g/seg/label", Label(label="grasp"), log_time_ns=300, publish_time_ns=42)
    got = list(read_messages(path))
    assert [t for t, _, _ in got] == [TOPIC] * 5 + ["handflow/g/cam/image", "handflow/g/seg/label"]
    np.testing.assert_array_equal(got[3][1].data, _array(3).data)
    assert got[3][1].header.seq == 4 and got[3][2] == 103
    np.testing.assert_array_equal(got[5][1].to_array(), img.to_array())

    with open(path, "rb") as f:  # what Foxglove sees: JSON channels with JSON schemas
        reader = make_reader(f)
        summary = reader.get_summary()
        channels = {c.topic: c for c in summary.channels.values()}
        schemas = {s.id: s for s in summary.schemas.values()}
        assert {c.message_encoding for c in channels.values()} == {"json"}
        assert {s.encoding for s in schemas.values()} == {"jsonschema"}
        assert schemas[channels["/" + TOPIC].schema_id].name == "handflow.Array"
        view = channels["/handflow/g/cam/image" + FOXGLOVE_IMAGE_SUFFIX]
        assert schemas[view.schema_id].name == "foxglove.RawImage"
        times = {(m.channel_id, m.log_time): m for _, _, m in reader.iter_messages()}
    label = times[(channels["/handflow/g/seg/label"].id, 300)]
    assert label.publish_time == 42
    pic = json.loads(times[(view.id, 200)].data)
    assert pic["timestamp"] == {"sec": 2, "nsec": 500_000_123}
    assert (pic["width"], pic["height"], pic["encoding"], pic["step"]) == (5, 4, "rgb8", 15)
    assert base64.b64decode(pic["data"]) == img.data


def test_default_recording_is_rosbag2_cdr_read_by_rosbags_and_mcap_ros2(tmp_path):
    rosbags = pytest.importorskip("rosbags.highlevel")
    typesys = pytest.importorskip("rosbags.typesys")
    mcap_ros2 = pytest.importorskip("mcap_ros2.reader")
    path = tmp_path / "a.mcap"
    img = Image.from_array(np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3))
    img.header = Header("cam", 7, 2_500_000_123)
    with McapWriter(path) as w:
        for i in range(5):
            w.write(TOPIC, _array(i), log_time_ns=100 + i)
        w.write("handflow/g/cam/image", img, log_time_ns=200)
    got = list(read_messages(path))
    assert [t for t, _, _ in got] == [TOPIC] * 5 + ["handflow/g/cam/image"]
    np.testing.assert_array_equal(got[3][1].data, _array(3).data)
    assert got[3][1].header.seq == 4 and got[3][1].header.source == "src" and got[3][2] == 103
    assert got[5][1].header == img.header and np.array_equal(got[5][1].to_array(), img.to_array())
    with open(path, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
        assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
        names = {s.name for s in summary.schemas.values()}
        assert names == {"handflow_msgs/msg/Array", "sensor_msgs/msg/Image"}  # no second copy of the pixels
        assert summary.chunk_indexes and {c.compression for c in summary.chunk_indexes} == {"zstd"}
    store = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    with rosbags.AnyReader([path], default_typestore=store) as r:
        seen = [(c.topic, r.deserialize(raw, c.msgtype)) for c, _, raw in r.messages()]
    assert [t for t, _ in seen] == ["/" + TOPIC] * 5 + ["/handflow/g/cam/image"]  # ROS 2 names
    assert list(seen[3][1].data) == list(_array(3).data) and seen[5][1].data.tobytes() == img.data
    decoded = [(m.channel.topic, m.ros_msg) for m in mcap_ros2.read_ros2_messages(str(path))]
    assert decoded[5][1].header.stamp.sec == 2 and decoded[5][1].header.stamp.nanosec == 500_000_123


def test_images_without_foxglove_view(tmp_path):
    path = tmp_path / "a.mcap"
    with McapWriter(path, foxglove_images=False, encoding="json") as w:
        w.write("handflow/g/cam/image", Image.from_array(np.zeros((2, 2), np.uint8)))
    assert list(read_report(path).channels) == ["handflow/g/cam/image"]


def test_topic_filter_globs_and_internal_ports():
    f = TopicFilter(["glove/*", "sim/joint*"])
    assert f("handflow/x/glove/frames") and f("handflow/x/sim/joints")
    assert not f("handflow/x/sim/contacts") and not f("handflow/x/glove/_health")
    everything = TopicFilter(None)
    assert everything("handflow/x/a/b") and not everything("handflow/x/a/_health")
    assert not everything("handflow/x/_clock")
    assert TopicFilter(["*/_health"])("handflow/x/a/_health")
    assert TopicFilter(["handflow/x/**"])("handflow/x/a/b") and not TopicFilter(["handflow/y/**"])("handflow/x/a/b")
    assert TopicFilter(["/handflow/x/a/*"])("handflow/x/a/b")  # a ROS 2 name as in the file


def test_peek_header_matches_full_decode():
    msg = _array(5)
    msg.header.source = 'we"ird'
    from handflow.framework.messages import encode

    hdr = peek_header(encode(msg))
    assert (hdr.type_name, hdr.source, hdr.seq, hdr.stamp_ns) == ("handflow.Array", 'we"ird', 6, 1_000_005)


def test_truncated_file_recovers_complete_chunks_at_every_cut(tmp_path):
    full = _write(tmp_path / "full.mcap", n=400, chunk_size=2048)
    data = full.read_bytes()
    complete = read_report(full)
    assert complete.complete and complete.messages == 400
    original = [rm.data for rm in iter_recording(full)]
    recovered_counts = []
    for frac in (0.0005, 0.1, 0.35, 0.6, 0.9, 0.999):
        cut = tmp_path / f"cut{frac}.mcap"
        cut.write_bytes(data[: max(1, int(len(data) * frac))])
        report = ReadReport(cut)
        got = [rm.data for rm in iter_recording(cut, report=report)]
        assert report.recovered and "ends inside a record" in report.error
        assert got == original[: len(got)]  # a prefix, never a half-written chunk
        recovered_counts.append(report.messages)
    assert recovered_counts == sorted(recovered_counts)
    assert recovered_counts[0] == 0 and 0 < recovered_counts[2] < 400 and recovered_counts[-1] >= 390


def test_inspect_json_on_complete_and_truncated_files(tmp_path, capsys):
    full = _write(tmp_path / "full.mcap", n=101, chunk_size=1024)
    assert inspect_cmd.run(argparse.Namespace(file=str(full), json=True)) == 0
    out = json.loads(capsys.readouterr().out)
    assert {"total_messages", "start_ns", "end_ns", "topics", "recovered"} <= set(out)
    assert out["total_messages"] == 101 and out["recovered"] is False
    assert (out["start_ns"], out["end_ns"]) == (0, 1_000_000_000)
    (topic,) = out["topics"]
    assert {"topic", "type", "count", "rate_hz"} <= set(topic)
    assert (topic["topic"], topic["type"], topic["count"]) == (TOPIC, "handflow.Array", 101)

    cut = tmp_path / "cut.mcap"
    cut.write_bytes(full.read_bytes()[: full.stat().st_size // 2])
    assert inspect_cmd.run(argparse.Namespace(file=str(cut), json=True)) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["recovered"] is True and 0 < out["total_messages"] < 101
    assert out["recovered_messages"] == out["total_messages"]
    assert inspect_cmd.run(argparse.Namespace(file=str(cut), json=False)) == 0
    assert f"{out['total_messages']} message(s) recovered" in capsys.readouterr().out


def test_inspect_rates_topics_by_their_stamps_not_a_start_up_burst(tmp_path):
    """As the demo's labels: 50 Hz stamps, the first 2 s received in one burst after a slow start
    (receive times alone gave 64 Hz); a topic whose stamps do not advance is rated by receive times."""
    path = tmp_path / "burst.mcap"
    with McapWriter(path, flush_interval_s=None) as w:
        for i in range(500):
            label = Label(label="grasp")
            label.header = Header("seg", i, 20_000_000 * i)
            w.write("handflow/g/seg/labels", label, log_time_ns=max(2_300_000_000 + i, 20_000_000 * i))
        for i in range(5):
            w.write("handflow/g/sim/description", Array(data=[1.0]), log_time_ns=2_000_000_000 * i)
    rates = {t["topic"]: t["rate_hz"] for t in inspect_cmd.summarize(str(path))["topics"]}
    assert rates == {"handflow/g/seg/labels": pytest.approx(50.0), "handflow/g/sim/description": pytest.approx(0.5)}


def test_inspect_rejects_non_mcap_and_missing_files(tmp_path, capsys):
    bad = tmp_path / "notes.mcap"
    bad.write_text("hello, not an mcap file")
    assert inspect_cmd.run(argparse.Namespace(file=str(bad), json=True)) == 2
    assert "not an MCAP file" in capsys.readouterr().err
    assert inspect_cmd.run(argparse.Namespace(file=str(tmp_path / "none.mcap"), json=True)) == 2
    assert "cannot read recording" in capsys.readouterr().err


@pytest.mark.parametrize("head", [b"", b"abc", b"\x89MCAP"])
def test_inspect_of_a_file_too_short_for_the_magic_is_not_mcap(tmp_path, capsys, head):
    """An empty or 3-byte file is no recording (exit 2), not a recovered one with 0 messages."""
    bad = tmp_path / "short.mcap"
    bad.write_bytes(head)
    assert inspect_cmd.run(argparse.Namespace(file=str(bad), json=False)) == 2
    err = capsys.readouterr().err
    assert "not an MCAP file" in err and "RECOVERED" not in err


def test_inspect_of_a_file_cut_after_its_magic_is_recovered(tmp_path, capsys):
    """A valid start that ends early is a truncated recording: recovered, exit 0; so is a recording
    just opened (its writer puts the magic on disk at once)."""
    path = tmp_path / "cut.mcap"
    path.write_bytes(b"\x89MCAP0\r\n")
    live = McapWriter(tmp_path / "live.mcap")
    try:
        for f in (path, live.path):
            assert inspect_cmd.run(argparse.Namespace(file=str(f), json=True)) == 0
            summary = json.loads(capsys.readouterr().out)
            assert summary["recovered"] and summary["total_messages"] == 0
    finally:
        live.close()


def test_writer_is_thread_safe(tmp_path):
    path = tmp_path / "threads.mcap"
    w = McapWriter(path, chunk_size=4096, flush_interval_s=0.01)
    barrier = threading.Barrier(4)

    def work(k):
        barrier.wait()
        for i in range(250):
            w.write(f"handflow/g/n{k}/out", _array(i))

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    w.close()
    per_topic: dict[str, list[int]] = {}
    for topic, msg, _ in read_messages(path):
        per_topic.setdefault(topic, []).append(msg.header.seq)
    assert dict(per_topic.items()) == {f"handflow/g/n{k}/out": list(range(1, 251)) for k in range(4)}
    with pytest.raises(RecordingError, match="closed"):
        w.write(TOPIC, _array(0))


_KILLED_WRITER = """
import sys, time, numpy as np
from handflow.framework.messages import Array, Header
from handflow.framework.files.mcap_writer import McapWriter
w = McapWriter(sys.argv[1], chunk_size=1 << 20, flush_interval_s=0.1)
i = 0
while True:
    i += 1
    m = Array(data=np.full(3, float(i))); m.header = Header("src", i, i)
    w.write("handflow/g/src/out", m)
    if i == 50:
        print("ready", flush=True)
    time.sleep(0.002)
"""


def test_kill_9_during_writing_leaves_a_recoverable_file(tmp_path):
    path = tmp_path / "killed.mcap"
    proc = subprocess.Popen([sys.executable, "-c", _KILLED_WRITER, str(path)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "ready"
    time.sleep(0.5)  # several time-based flushes; the 1 MB chunk size alone would never flush
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    report = ReadReport(path)
    seqs = [rm.decode().header.seq for rm in iter_recording(path, report=report)]
    assert report.recovered and len(seqs) >= 50
    assert seqs == list(range(1, len(seqs) + 1))


def test_graph_recorder_stores_graph_params_and_named_files(tmp_path):
    (tmp_path / "rows.csv").write_text("a,b\n1,2\n3,4\n")
    graph_file = tmp_path / "g.yaml"
    graph_file.write_text(
        "name: prov\nnodes:\n"
        "  - id: source\n    plugin: basic.signal\n    params: {kind: csv, csv: rows.csv, rate_hz: 10}\n"
        "  - id: sink\n    plugin: basic.sink\n    inputs: {in: source/out}\n"
    )
    graph = load_graph(graph_file)
    rec = GraphRecorder.for_graph(graph, tmp_path / "p.mcap")
    rec.writer.write("handflow/prov/source/out", _array(1))
    rec.close()
    report = read_report(tmp_path / "p.mcap")
    assert report.metadata["handflow.graph"]["name"] == "prov"
    assert json.loads(report.metadata["handflow.params"]["source"])["csv"] == "rows.csv"
    assert report.metadata["handflow.plugins"] == {"source": "basic.signal", "sink": "basic.sink"}
    assert report.metadata["handflow.files"] == {"source.csv": "files/rows.csv"}
    assert report.attachments["files/rows.csv"].data == b"a,b\n1,2\n3,4\n"
    assert report.attachments["graph.yaml"].data == graph_file.read_bytes()
    assert report.messages == 1


def test_migrate_rewrites_a_json_recording_as_rosbag2_cdr(tmp_path):
    from handflow.recordings import __file__ as shipped

    src = Path(shipped).parent / "gestures.mcap"
    out = tmp_path / "new.mcap"
    proc = subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", "migrate", str(src), str(out)], capture_output=True, text=True
    )
    assert proc.returncode == 0 and "rosbag2 CDR" in proc.stdout, proc.stderr
    old, new = list(iter_recording(src)), list(iter_recording(out))
    assert {rm.encoding for rm in old} == {"json"} and {rm.encoding for rm in new} == {"cdr"}
    assert [(a.topic, a.log_time_ns, a.publish_time_ns, a.sequence) for a in old] == [
        (b.topic, b.log_time_ns, b.publish_time_ns, b.sequence) for b in new
    ]
    for a, b in zip(old[::50], new[::50]):
        da, db = a.decode().to_dict(), b.decode().to_dict()
        assert db["header"].pop("source") == a.topic.split("/")[2]  # CDR records: the topic's node
        da["header"].pop("source")
        assert da == db
    assert read_report(out).metadata == read_report(src).metadata
    same = subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", "migrate", str(out), str(out)], capture_output=True, text=True
    )
    assert same.returncode == 2 and "new file" in same.stderr


def test_a_second_type_on_a_topic_gets_its_own_channel(tmp_path):
    path = tmp_path / "a.mcap"
    with McapWriter(path) as w:
        w.write(TOPIC, _array(1))
        w.write(TOPIC, Label(label="stray"))  # e.g. published by an outside peer
        w.write(TOPIC, _array(2))
    assert [type(m).__name__ for _, m, _ in read_messages(path)] == ["Array", "Label", "Array"]


def test_a_second_of_camera_frames_is_one_chunk(tmp_path):
    """The writer keeps an index entry per chunk until the summary: at the flagship's camera rate a
    second of frames (5 × 320×240 RGB) fills one default chunk, not one per frame (docs/recording.md)."""
    path = tmp_path / "cam.mcap"
    rng = np.random.default_rng(0)
    with McapWriter(path, flush_interval_s=None) as w:
        for i in range(5):
            img = Image.from_array(rng.integers(0, 255, size=(240, 320, 3), dtype=np.uint8))
            img.header = Header("cam", i + 1, 1_000 + i)
            w.write("handflow/g/cam/image", img, log_time_ns=1_000 + i)
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary.statistics.message_count == 5
    assert len(summary.chunk_indexes) == 1
