"""A disk that fills during recording: a clear error, the file readable up to then, the graph unharmed.

The full disk is simulated with a file-size limit (``RLIMIT_FSIZE``, with ``SIGXFSZ`` ignored so
that a write fails with ``EFBIG`` as it would with ``ENOSPC``); docs/reliability.md.
"""

from __future__ import annotations

import json
import resource
import signal
import subprocess
import sys

import pytest

from handflow.framework.files.mcap_reader import read_report
from handflow.framework.files.mcap_writer import McapWriter, RecordingError
from handflow.framework.messages import Array, Header
from tests.framework._rec_helpers import chain, unique

LIMIT = 16_000  # bytes: the header, metadata and a few seconds of the chain


def _file_size_limit():
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


_WRITER = """
import sys
import numpy as np
from handflow.framework.messages import Array, Header
from handflow.framework.files.mcap_writer import McapWriter, RecordingError
w = McapWriter(sys.argv[1], chunk_size=2048, flush_interval_s=None)
rng = np.random.default_rng(0)
try:
    for i in range(2000):
        m = Array(data=rng.random(16))
        m.header = Header("src", i + 1, i + 1)
        w.write("handflow/t/src/out", m)
except RecordingError as exc:
    print("ERROR", exc)
    try:
        w.write("handflow/t/src/out", m)
    except RecordingError as again:
        print("AGAIN", again)
    w.close()
    print("WRITTEN", w.message_count)
"""


def test_a_writer_on_a_full_disk_raises_a_recording_error_and_keeps_its_complete_chunks(tmp_path):
    path = tmp_path / "full.mcap"
    proc = subprocess.run(
        [sys.executable, "-c", _WRITER, str(path)], preexec_fn=_file_size_limit, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    lines = dict(line.split(" ", 1) for line in proc.stdout.splitlines())
    assert "recording stopped: cannot write" in lines["ERROR"] and "File too large" in lines["ERROR"]
    assert "free disk space" in lines["ERROR"]
    assert lines["AGAIN"] == lines["ERROR"]  # later writes say the same, nothing else escapes
    report = read_report(path)
    assert not report.complete
    assert 0 < report.messages <= int(lines["WRITTEN"])
    assert path.stat().st_size <= LIMIT


def test_a_closed_writer_refuses_writes_with_its_own_error(tmp_path):
    w = McapWriter(tmp_path / "x.mcap")
    w.close()
    m = Array(data=[1.0])
    m.header = Header("s", 1, 1)
    with pytest.raises(RecordingError, match="closed"):
        w.write("handflow/t/s/out", m)


@pytest.mark.slow
def test_a_disk_filling_during_handflow_run_is_a_clear_error_and_no_node_is_harmed(tmp_path):
    graph = chain(tmp_path / "g.yaml", unique("diskfull"), rate=100)
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "handflow.framework.cli",
            "run",
            str(graph),
            "--duration",
            "8",
            "--record",
            "r.mcap",
            "--summary-json",
            "s.json",
        ],
        cwd=tmp_path,
        preexec_fn=_file_size_limit,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 1, proc.stderr[-2000:]
    assert "error: recording stopped: cannot write" in proc.stderr and "File too large" in proc.stderr
    assert "Traceback" not in proc.stderr
    report = read_report(tmp_path / "r.mcap")
    assert report.messages > 0
    summary = json.loads((tmp_path / "s.json").read_text())
    assert all(unit["restarts"] == 0 for unit in summary.values())
    # every node process ran on to the orderly end of --duration: none restarted, none failed
    assert all(code in (0, None) for unit in summary.values() for code in unit["exit_codes"])
