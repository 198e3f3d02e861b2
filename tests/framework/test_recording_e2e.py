"""Recording real graphs: SIGINT during `handflow run --record`, and `handflow record` from outside."""

from __future__ import annotations

import json
import signal

import pytest

from handflow.framework.discovery import live_runs
from handflow.framework.recording import read_report
from tests.framework._rec_helpers import chain, handflow, start, unique, wait_until

pytestmark = pytest.mark.slow


@pytest.fixture(autouse=True)
def private_run_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))


def _recorded(path) -> int:
    return read_report(path).messages if path.exists() else 0


def test_sigint_during_recording_leaves_a_complete_mcap(tmp_path):
    graph = chain(tmp_path / "g.yaml", unique("recint"))
    out = tmp_path / "run.mcap"
    proc = start("run", str(graph), "--record", str(out))
    try:
        wait_until(lambda: _recorded(out) >= 40, what="the first flushed chunks")  # readable while being written
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    report = read_report(out)
    assert report.complete and not report.error
    topics = {t.rsplit("/", 2)[-2] + "/" + t.rsplit("/", 1)[-1] for t in report.channels}
    assert topics == {"source/out", "scale/out"}  # data topics only, no _health
    assert report.messages >= 40
    assert report.metadata["handflow.graph"]["file"] == str(graph)
    assert json.loads(report.metadata["handflow.params"]["scale"]) == {"gain": 2.0, "offset": 0.0}


def test_record_command_joins_a_running_graph(tmp_path):
    name = unique("recout")
    graph = chain(tmp_path / "g.yaml", name)
    missing = handflow("record", name, "--out", str(tmp_path / "none.mcap"), "--duration", "1")
    assert missing.returncode == 2 and f"no running graph '{name}'" in missing.stderr

    proc = start("run", str(graph))
    try:
        wait_until(lambda: any(r.graph == name for r in live_runs()), what="the run-file")
        rec = handflow("record", name, "--out", str(tmp_path / "out.mcap"), "--duration", "2", "--topics", "source/*")
        assert rec.returncode == 0, rec.stderr
        assert "recorded" in rec.stdout
    finally:
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=60)
    assert not live_runs()  # the launcher removed its run-file
    summary = json.loads(handflow("inspect", str(tmp_path / "out.mcap"), "--json").stdout)
    assert [t["topic"] for t in summary["topics"]] == [f"handflow/{name}/source/out"]
    assert summary["recovered"] is False and summary["topics"][0]["count"] >= 100
    assert summary["topics"][0]["rate_hz"] == pytest.approx(100, rel=0.25)
    assert "graph.yaml" in summary["attachments"]  # provenance found through the run-file
