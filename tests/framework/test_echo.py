"""``handflow echo`` (docs/monitoring.md, "One topic's messages"): topic names, the ros2-style blocks, and
the command on a running graph."""

from __future__ import annotations

import json
import signal

import pytest
import yaml

from handflow.framework.commands.echo import parse_topic, shown
from handflow.framework.messages import Array, Header
from handflow.framework.testkit.fuzzing import sample_messages
from tests.framework._rec_helpers import chain, handflow, start, unique, wait_until


def test_topics_are_node_port_or_full_keys():
    assert parse_topic("scale/out") == (None, "scale", "out")
    assert parse_topic("handflow/g/scale/out") == ("g", "scale", "out")
    assert parse_topic("/handflow/g/scale/out") == ("g", "scale", "out")  # the ROS 2 name (recordings, Foxglove)
    assert parse_topic("scale/_health") == (None, "scale", "_health")
    for bad in ("scale", "scale/", "a/b/c", "handflow/out", "handflow/g//out", ""):
        assert parse_topic(bad) is None, bad


def test_messages_show_as_yaml_blocks_with_long_lists_cut():
    msg = Array(data=list(range(300)), shape=[300])
    msg.header = Header("scale", 7, 123)
    text = shown(msg.to_dict(), truncate=10)
    assert text.endswith("\n---") and "type" not in text
    block = yaml.safe_load(text.removesuffix("---"))
    assert block["header"] == {"source": "scale", "seq": 7, "stamp_ns": 123}
    assert block["data"] == [*range(10), "..."] and block["shape"] == [300]
    assert yaml.safe_load(shown(msg.to_dict(), truncate=0).removesuffix("---"))["data"] == list(range(300))


def test_every_message_type_shows_as_yaml_and_json():
    for msg in sample_messages():
        d = msg.to_dict()
        block = yaml.safe_load(shown(d, truncate=0).removesuffix("---"))
        assert block == {k: v for k, v in json.loads(json.dumps(d)).items() if k != "type"}, msg.TYPE


@pytest.mark.slow
def test_echo_prints_n_messages_of_a_running_topic_and_refuses_unknown_ones(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    name = unique("echo")
    run = start("run", str(chain(tmp_path / "g.yaml", name)), cwd=tmp_path)
    try:
        wait_until(lambda: handflow("param", "get", "sink", cwd=tmp_path).returncode == 0, 60, "the graph")
        echoed = handflow("echo", "scale/out", "-n", "5", "--json", cwd=tmp_path)
        assert echoed.returncode == 0, echoed.stderr
        lines = [json.loads(line) for line in echoed.stdout.splitlines()]
        assert len(lines) == 5 and all(m["type"] == "handflow.Array" and len(m["data"]) == 3 for m in lines)
        seqs = [m["header"]["seq"] for m in lines]
        assert seqs == list(range(seqs[0], seqs[0] + 5))  # five in a row, none lost
        once = handflow("echo", f"handflow/{name}/source/out", "--once", cwd=tmp_path)
        assert once.returncode == 0 and once.stdout.count("---") == 1 and "header:\n  source: source" in once.stdout
        port = handflow("echo", "scale/outt", cwd=tmp_path)
        assert port.returncode == 2 and "no output port 'outt'; its outputs: scale/out" in port.stderr
        node = handflow("echo", "scael/out", cwd=tmp_path)
        assert node.returncode == 2 and "has no node 'scael' (its nodes: scale, sink, source)" in node.stderr
    finally:
        run.send_signal(signal.SIGINT)
        run.communicate(timeout=60)
