"""basic.sink's JSON lines: a new run replaces the file, a restart within the run continues it."""

from __future__ import annotations

import json

from handflow.framework.messages import Label
from handflow.framework.runtime.runner import SeqState
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.basic.sink import Sink


def _run(path, labels: list[str], restarted: bool = False) -> None:
    h = NodeHarness(Sink, {"jsonl": str(path)})
    h.ctx.restarted = restarted
    h.setup()
    for label in labels:
        h.send("in", Label(label=label))
    h.teardown()


def _labels(path) -> list[str]:
    return [json.loads(line)["msg"]["label"] for line in path.read_text().splitlines()]


def test_a_second_run_replaces_the_file_and_a_restart_continues_it(tmp_path):
    path = tmp_path / "out" / "labels.jsonl"
    _run(path, ["a", "b", "c"])
    assert _labels(path) == ["a", "b", "c"]
    _run(path, ["d", "e"])  # a new run: never appended to the old run's lines
    assert _labels(path) == ["d", "e"]
    _run(path, ["f"], restarted=True)  # the same run after a crash: nothing of it is lost
    assert _labels(path) == ["d", "e", "f"]


def test_the_runtime_tells_a_restarted_node_by_its_state_file(tmp_path):
    first = SeqState(tmp_path / "sink.seq", ["in:in"])
    first.set("in:in", 5)
    again = SeqState(tmp_path / "sink.seq", ["in:in"])  # the launcher restarts the node: same state dir
    assert (first.resumed, again.resumed, again.get("in:in")) == (False, True, 5)
    assert not SeqState(None, ["in:in"]).resumed
