"""configs/glove_emulated.yaml runs end to end with `handflow run` (no glove needed)."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

GRAPH = Path(__file__).resolve().parents[2] / "configs" / "glove_emulated.yaml"


@pytest.mark.slow
def test_glove_emulated_graph_runs():
    proc = subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(GRAPH), "--duration", "4"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    received = re.search(r"\[handflow\.node\.sink\] received (\d+) message", proc.stderr)
    assert received and int(received.group(1)) > 50, proc.stderr[-2000:]
