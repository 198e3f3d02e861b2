"""Shared helpers of the recording/replay/monitor tests: graphs with unique names, CLI processes."""

from __future__ import annotations

import json
import subprocess
import sys
import time
import uuid
from pathlib import Path

from tests.conftest import kill_processes_of, processes_of

REPO = Path(__file__).resolve().parents[2]


def unique(prefix: str) -> str:
    """A graph name no other test (or engineer) on this machine uses at the same time."""
    return f"{prefix}_{uuid.uuid4().hex[:8]}"


def write_graph(path: Path, name: str, body: str) -> Path:
    path.write_text(f"name: {name}\n{body}")
    return path


def chain(path: Path, name: str, rate: float = 100) -> Path:
    """source (seeded noise) → scale (×2) → sink: a live graph to record or monitor."""
    return write_graph(
        path,
        name,
        f"""nodes:
  - id: source
    plugin: basic.signal
    params: {{kind: noise, rate_hz: {rate}, width: 3, seed: 1}}
  - id: scale
    plugin: basic.transform
    params: {{gain: 2.0}}
    inputs: {{in: source/out}}
  - id: sink
    plugin: basic.sink
    inputs: {{in: scale/out}}
""",
    )


def start(*args: str, cwd: Path = REPO) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", *args],
        cwd=cwd,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )


def handflow(*args: str, cwd: Path = REPO, timeout: float = 90) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def ended_within(proc: subprocess.Popen, seconds: float, folder: Path, what: str, sig: int | None = None) -> str:
    """The stderr of ``proc`` (sent ``sig`` first, if given) once it has exited, which must be within ``seconds``
    and leave no process it started (:func:`tests.conftest.processes_of` ``folder``); otherwise all of them are
    killed and the test fails."""
    if sig is not None:
        proc.send_signal(sig)
    try:
        _, err = proc.communicate(timeout=seconds)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
        left = kill_processes_of(folder)
        raise AssertionError(
            f"{what}: still running {seconds:.0f}s after the signal; killed it and {left}\n{err[-3000:]}"
        ) from None
    try:
        wait_until(lambda: not processes_of(folder), timeout=5.0, what="its processes to exit")
    except AssertionError:
        left = kill_processes_of(folder)
        raise AssertionError(
            f"{what}: exited {proc.returncode}, leaving processes {left} (killed)\n{err[-3000:]}"
        ) from None
    return err


def wait_until(pred, timeout: float = 30.0, what: str = "condition") -> None:
    deadline = time.monotonic() + timeout
    while not pred():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.1)


def read_jsonl(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def wait_counted(session, graph: str, counters: dict[str, str], timeout: float = 60.0) -> None:
    """Until each node of ``counters`` (node id → a counter of its heartbeat: ``handled.PORT``,
    ``published.PORT``) reports it above 0 on ``_health``, which crosses every link whoever reads: the graph's
    nodes are up and its data flows to them, across machines too."""
    from handflow.framework.recorder.replay import GraphWatcher

    watcher = GraphWatcher(session, graph)
    try:
        if not watcher.wait_for(
            lambda: all(watcher.health.get(n, {}).get(c, 0) > 0 for n, c in counters.items()), timeout
        ):
            raise AssertionError(f"timed out waiting for {counters} of graph '{graph}': {watcher.health}")
    finally:
        watcher.close()
