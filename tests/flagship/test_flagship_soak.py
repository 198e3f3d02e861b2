"""The CI version of the soak (benchmarks/soak.py, docs/reliability.md): a minute of the flagship with
camera and recording (about 30 000 messages) — no restarts, loss (sequence gaps in the recording and
input gaps the nodes counted) below 0.1 % of the recorded messages, every process's memory steady over
the 40 s after a 20 s warm-up (RSS every 5 s).  Slow leaks are the hour-long benchmark's to find
(docs/benchmarks.md, "Soak"); ``HANDFLOW_SOAK_SECONDS`` runs this one longer."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from tests.conftest import REPO

pytestmark = pytest.mark.slow
SECONDS = float(os.environ.get("HANDFLOW_SOAK_SECONDS", "60"))


def test_a_minute_of_the_flagship_loses_nothing_and_restarts_nothing(tmp_path):
    proc = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "soak.py"), "--duration", str(SECONDS), "--sample", "5", "--json"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=SECONDS + 240,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads(proc.stdout)
    assert result["restarts"] == 0
    assert result["recorded_messages"] > 30 * SECONDS  # the glove alone publishes 50 frames/s
    assert result["lost_messages"] <= 0.001 * result["recorded_messages"], result["lost_in_recording_by_topic"]
    assert result["rss_growth_max"] is not None and result["rss_growth_max"] < 0.25, result["rss"]
