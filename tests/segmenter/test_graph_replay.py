"""The online segmenter node in a real graph, fed by a replayed MCAP recording (lock-step)."""

import json
import subprocess
import sys
import uuid

import pytest

from handflow.framework.files.mcap_writer import McapWriter
from handflow.framework.messages import Array, Header
from handflow.plugins.segmenter import save_class_models

T0 = 1_700_000_000_000_000_000


@pytest.mark.slow
def test_online_clm_node_in_a_graph_fed_by_a_replayed_recording(tmp_path, monkeypatch, ukr_models, two_letters):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    Y, truth = two_letters
    models = save_class_models(ukr_models, tmp_path / "models")
    recording = tmp_path / "pen.mcap"
    with McapWriter(recording) as w:
        for i, y in enumerate(Y):
            t = T0 + i * 10_000_000
            msg = Array(data=y)
            msg.header = Header("pen", i + 1, t)
            w.write("handflow/pen_rec/pen/out", msg, log_time_ns=t)
    graph = tmp_path / "seg.yaml"
    graph.write_text(f"""name: seg_{uuid.uuid4().hex[:8]}
external: {{pen/out: Array}}
nodes:
  - id: seg
    plugin: segmenter.online_clm
    params: {{models: {models}, window: 200, history: 10, seed: 0}}
    inputs: {{array: pen/out}}
  - id: labels
    plugin: basic.sink
    params: {{jsonl: labels.jsonl}}
    inputs: {{in: seg/labels}}
""")
    proc = subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", "replay", str(recording), "--into", str(graph), "--lockstep"],
        cwd=tmp_path,  # outputs (the sink's jsonl) land relative to the current directory
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert proc.returncode == 0, proc.stderr
    rows = [json.loads(line)["msg"] for line in (tmp_path / "labels.jsonl").read_text().splitlines()]
    assert len(rows) == len(Y)
    assert [r["index"] for r in rows] == list(range(len(Y)))
    assert [r["header"]["stamp_ns"] for r in rows] == [T0 + i * 10_000_000 for i in range(len(Y))]
    online = ["AB"[t] for t in truth]
    agree = sum(r["label"] == c for r, c in zip(rows, online)) / len(rows)
    assert agree > 0.8
