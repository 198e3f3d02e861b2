"""kill -9 of every kind of node process during the flagship (docs/reliability.md): each is restarted,
the recording goes on and stays valid, the restarts are events in it and the gaps are counted."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from handflow.framework.files.mcap_reader import read_messages, read_report
from handflow.framework.messages import RuntimeEvent
from tests.conftest import REPO

pytestmark = pytest.mark.slow


def _children(pid: int) -> list[str]:
    try:
        return Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    except OSError:
        return []


def _units(launcher_pid: int) -> dict[str, int]:
    """Node processes of a launcher (forked by its zygote): their ``--nodes`` argument → pid (zombies excluded)."""
    out = {}
    for pid in [p for z in _children(launcher_pid) for p in _children(int(z))]:
        try:
            if Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z":
                continue
            argv = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode().split()
        except OSError:
            continue
        if "--nodes" in argv:
            out[argv[argv.index("--nodes") + 1]] = int(pid)
    return out


def _wait(pred, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while not (value := pred()):
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.2)
    return value


def test_kill_9_of_every_node_process_is_survived(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    rec, summary = tmp_path / "demo.mcap", tmp_path / "summary.json"
    proc = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(REPO / "configs/demo.yaml")]
        + ["--record", str(rec), "--summary-json", str(summary)],
        cwd=tmp_path,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    killed = []
    try:
        units = _wait(lambda: len(u := _units(proc.pid)) >= 6 and u, 120, "every node process")
        _wait(lambda: rec.exists() and read_report(rec).messages > 500, 120, "the recording to fill")
        for name, pid in sorted(units.items()):
            proc_units = _units(proc.pid)
            pid = proc_units.get(name, pid)
            subprocess.run(["kill", "-9", str(pid)], check=True)
            killed.append(name)
            _wait(lambda n=name, p=pid: _units(proc.pid).get(n, p) != p, 60, f"'{name}' restarted")
            time.sleep(1.0)
        before_stop = read_report(rec).messages
        time.sleep(3.0)
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=90)
    assert proc.returncode == 0, err[-3000:]
    report = read_report(rec)
    assert report.complete and report.messages > before_stop
    restarts = {",".join(s["nodes"]): s["restarts"] for s in json.loads(summary.read_text()).values()}
    assert all(restarts[name] == 1 for name in killed), restarts
    events = [m for t, m, _ in read_messages(rec) if t.endswith("/_runtime/events") and isinstance(m, RuntimeEvent)]
    assert {e.node for e in events if e.kind == "restart"} == set(killed)
