"""The console examples of docs/recording.md and docs/monitoring.md, run as written, in a scratch copy of
``configs/``, ``docs/`` and ``recordings/`` (outputs land there), and the outcomes the pages state."""

from __future__ import annotations

import json
import re
import shlex
import shutil
import signal
import subprocess
import sys

import pytest
import yaml

from handflow.framework.runtime.discovery import live_runs
from tests.framework._rec_helpers import REPO, wait_until

pytestmark = pytest.mark.slow


def console_commands(doc: str) -> list[str]:
    blocks = re.findall(r"```console\n(.*?)```", (REPO / "docs" / doc).read_text(), re.S)
    return [line[2:].strip() for block in blocks for line in block.splitlines() if line.startswith("$ ")]


def _argv(cmd: str) -> list[str]:
    words = shlex.split(cmd)
    assert words[0] == "handflow", cmd
    return [sys.executable, "-m", "handflow.framework.cli", *words[1:]]


@pytest.mark.parametrize("doc", ["recording.md", "monitoring.md"])
def test_documented_commands_run(doc, tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    monkeypatch.setenv("PYTHONPATH", str(REPO))
    ws = tmp_path / "ws"
    for name in ("configs", "docs", "recordings"):
        shutil.copytree(REPO / name, ws / name, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.chdir(ws)
    jobs: list[subprocess.Popen] = []
    commands = console_commands(doc)
    assert commands
    try:
        for cmd in commands:
            if cmd.startswith("kill -INT %"):
                job = jobs[int(cmd.rsplit("%", 1)[1]) - 1]
                job.send_signal(signal.SIGINT)
                assert job.wait(timeout=60) == 0, cmd
            elif cmd.endswith("&"):
                argv = _argv(cmd[:-1])
                name = yaml.safe_load((ws / argv[-1]).read_text())["name"]
                jobs.append(subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
                wait_until(lambda name=name: any(r.graph == name for r in live_runs()), what=f"'{cmd}' to start")
            else:
                proc = subprocess.run(_argv(cmd), capture_output=True, text=True, timeout=150)
                assert proc.returncode == 0, f"{cmd}\n{proc.stdout}\n{proc.stderr}"
                if "--json" in cmd and "monitor" in cmd:
                    assert '"alive": true' in proc.stdout, proc.stdout
                if cmd.startswith("handflow echo") and "--json" in cmd:  # -n 5: five JSON objects
                    assert [json.loads(line)["type"] for line in proc.stdout.splitlines()] == ["handflow.Array"] * 5
                elif cmd.startswith("handflow echo"):  # --once: one YAML block
                    assert proc.stdout.count("---") == 1 and "header:" in proc.stdout, proc.stdout
                if cmd.startswith("handflow compare"):
                    _assert_replayed_labels_equal(cmd, ws)
    finally:
        for job in jobs:
            if job.poll() is None:
                job.kill()
                job.wait()


def _assert_replayed_labels_equal(cmd: str, ws) -> None:
    """recording.md: the lock-step replay recomputes every label of the live run, and its sink file holds
    that one replay's labels (a replay replaces it, never appends)."""
    out = json.loads(subprocess.run([*_argv(cmd), "--json"], capture_output=True, text=True, timeout=150).stdout)
    labels = next(t for t in out["topics"] if t["topic"] == "segmenter/labels")
    assert out["equal"] and labels["equal"] > 100, out
    assert len((ws / "out" / "replayed_labels.jsonl").read_text().splitlines()) == labels["equal"]
