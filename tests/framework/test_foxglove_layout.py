"""`handflow layout GRAPH`: the flagship's Foxglove layout for a graph's topics (docs/foxglove.md)."""

from __future__ import annotations

import json
import re
from pathlib import Path

from handflow.framework.graphs.model import load_graph
from handflow.framework.observe.foxglove_layout import carried, unshown

REPO = Path(__file__).resolve().parents[2]


def test_the_layout_for_the_replay_graph_names_its_topics_and_says_which_panels_stay_empty(tmp_path, run_handflow):
    out = tmp_path / "layout.json"
    proc = run_handflow("layout", "demo_segment_only", "-o", str(out), check=True)
    text = out.read_text()
    topics = set(re.findall(r"/handflow/(\w+)/(\w+/\w+)", text))
    assert {graph for graph, _ in topics} == {"demo_segment_only"}
    graph = load_graph(REPO / "configs" / "demo_segment_only.yaml")
    shown = {topic for _, topic in topics} & carried(graph)
    assert shown == {"shadow/joints", "segmenter/labels", "segmenter/events"}  # joint, label and event panels
    assert set(unshown(graph)) == {topic for _, topic in topics} - shown
    assert "camera/compressed" in proc.stderr and "sim/tf" in proc.stderr  # said to stay empty
    json.loads(text)  # Foxglove imports it
    assert (
        out.read_text().replace("demo_segment_only", "demo") == (REPO / "configs" / "foxglove_layout.json").read_text()
    )


def test_the_layout_for_the_demo_is_the_shipped_one(run_handflow):
    proc = run_handflow("layout", "demo", check=True)
    assert proc.stdout == (REPO / "configs" / "foxglove_layout.json").read_text()
    assert "stay empty" not in proc.stderr  # the demo carries every topic of it
