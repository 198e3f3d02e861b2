"""`handflow run` with lsl.inlet and lsl.outlet in their own processes, on loopback (docs/lsl.md)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

lsl = pytest.importorskip("mne_lsl.lsl")
pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]


def test_a_graph_reads_and_writes_lsl_streams(tmp_path):
    into, out = f"hf-in-{uuid.uuid4().hex[:6]}", f"hf-out-{uuid.uuid4().hex[:6]}"
    graph = tmp_path / "graph.yaml"
    graph.write_text(f"""name: lsl_e2e
nodes:
  - id: emg
    plugin: lsl.inlet
    params: {{source_id: {into}, resolve_timeout_s: 10}}
  - id: sink
    plugin: basic.sink
    params: {{jsonl: {tmp_path / "sink.jsonl"}}}
    inputs: {{in: emg/out}}
  - id: source
    plugin: basic.signal
    params: {{kind: sine, rate_hz: 50, width: 2}}
  - id: to-lsl
    plugin: lsl.outlet
    params: {{name: hf, source_id: {out}, sfreq: 50}}
    inputs: {{in: source/out}}
""")
    info = lsl.StreamInfo("emg", "EMG", 2, 100.0, "float32", into)
    outlet = lsl.StreamOutlet(info)
    proc = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(graph), "--duration", "4"],
        cwd=REPO,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    received, inlet, i = [], None, 0
    try:
        while proc.poll() is None:
            i += 1
            outlet.push_sample(np.array([i, -i], np.float32))
            if inlet is None:
                found = lsl.resolve_streams(timeout=0.05, source_id=out)
                if found:
                    inlet = lsl.StreamInlet(found[0])
                    inlet.open_stream(timeout=5)
            else:
                data, ts = inlet.pull_chunk(timeout=0.0)
                received += list(zip(np.asarray(data).tolist(), ts))
            time.sleep(0.01)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    rows = [json.loads(line)["msg"] for line in (tmp_path / "sink.jsonl").read_text().splitlines()]
    assert len(rows) > 100 and rows[-1]["type"] == "handflow.Array"
    values = [r["data"] for r in rows]
    assert all(v[1] == -v[0] for v in values) and values == sorted(values)
    assert len(received) > 50 and all(len(v) == 2 for v, _ in received)
    assert all(abs(t - lsl.local_clock()) < 30 for _, t in received)


def test_an_inlet_without_a_stream_fails_the_run_and_nothing_claims_ready(tmp_path):
    graph = tmp_path / "graph.yaml"
    graph.write_text(f"""name: lsl_absent
nodes:
  - id: emg
    plugin: lsl.inlet
    params: {{source_id: absent-{uuid.uuid4().hex[:6]}, resolve_timeout_s: 1}}
  - id: sink
    plugin: basic.sink
    inputs: {{in: emg/out}}
""")
    proc = subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(graph), "--duration", "2"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 3, proc.stderr  # the same setup error twice: a crash loop
    assert "all nodes ready" not in proc.stderr  # each node that did set up says "ready: NODE"; not all did
    assert "Traceback" not in proc.stderr
    assert (
        f"{graph}:3: emg (crash loop after 2 failed starts, not restarted): failed 2 times with the same error"
        in proc.stderr
    )
    assert proc.stderr.count("node 'emg': no LSL stream") == 1, proc.stderr  # once, as it first happened
