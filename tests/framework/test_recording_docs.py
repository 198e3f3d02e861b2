"""The console examples of docs/recording.md and docs/monitoring.md, run as written."""

from __future__ import annotations

import re
import shlex
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
    monkeypatch.chdir(REPO)
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
                name = yaml.safe_load((REPO / argv[-1]).read_text())["name"]
                jobs.append(subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
                wait_until(lambda name=name: any(r.graph == name for r in live_runs()), what=f"'{cmd}' to start")
            else:
                # outputs (recordings) go to the test's folder, not the repository
                argv = [a if not a.endswith(".mcap") else str(tmp_path / a) for a in _argv(cmd)]
                proc = subprocess.run(argv, capture_output=True, text=True, timeout=90)
                assert proc.returncode == 0, f"{cmd}\n{proc.stdout}\n{proc.stderr}"
                if "--json" in cmd and "monitor" in cmd:
                    assert '"alive": true' in proc.stdout, proc.stdout
    finally:
        for job in jobs:
            if job.poll() is None:
                job.kill()
                job.wait()
