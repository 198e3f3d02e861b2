"""``handflow run --watch``: how long a plugin edit takes to reach the stream (docs/benchmarks.md,
"Live parameters and reload"; docs/tuning.md).

A 50 Hz ``basic.signal`` feeds a plugin kept in a temporary folder (``temp.shift``: adds ``SHIFT``),
then a sink; the graph runs with ``--watch``.  Each edit changes ``SHIFT`` and is timed from the save
to the first output carrying the new value (``reload_s``); the source's longest pause around the
edit is measured from its messages' stamps in periods (``gap_periods``; the goal is under 3).
Baseline, in the same run: what an edit costs without ``--watch`` — the graph stopped (Ctrl-C) and
run again, from the stop to the first output (``restart_s``).

    python benchmarks/watch_reload.py [--edits 10] [--restarts 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from handflow.framework import keys, wire
from handflow.framework.runtime.discovery import join, live_runs
from handflow.framework.testkit.plugin_dist import register_plugins

RATE_HZ = 50.0
PLUGIN = """from handflow.framework.messages import Array
from handflow.framework.plugin import Node

SHIFT = {shift}


class Shift(Node):
    inputs = {{"in": Array}}
    outputs = {{"out": Array}}

    def on_message(self, port, msg):
        self.ctx.publish("out", Array(data=msg.data + SHIFT, shape=list(msg.shape)), stamp_ns=msg.header.stamp_ns)
"""
GRAPH = f"""name: {{name}}
nodes:
  - id: source
    plugin: basic.signal
    params: {{{{rate_hz: {RATE_HZ}}}}}
  - id: shift
    plugin: temp.shift
    inputs: {{{{in: source/out}}}}
  - id: sink
    plugin: basic.sink
    params: {{{{log_every: 0}}}}
    inputs: {{{{in: shift/out}}}}
"""


class Stream:
    """Stamps of ``source/out`` and (receive time, first value) of ``shift/out``."""

    def __init__(self, graph: str) -> None:
        self.session, _ = join(graph)
        self.lock = threading.Lock()
        self.source: list[tuple[int, float]] = []  # (seq, stamp s)
        self.shift: list[tuple[float, float]] = []  # (monotonic receive time, value)
        self.subs = [
            self.session.declare_subscriber(keys.topic_key(graph, "source", "out"), self._on_source),
            self.session.declare_subscriber(keys.topic_key(graph, "shift", "out"), self._on_shift),
        ]

    def _on_source(self, sample) -> None:
        header = wire.unpack(*wire.sample_parts(sample)).header
        with self.lock:
            self.source.append((header.seq, header.stamp_ns / 1e9))

    def _on_shift(self, sample) -> None:
        now, msg = time.monotonic(), wire.unpack(*wire.sample_parts(sample))
        with self.lock:
            self.shift.append((now, float(msg.data[0])))

    def first_shift_at_least(self, value: float, since: float, timeout: float = 30.0) -> float:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                hit = next((t for t, v in self.shift if t >= since and v >= value), None)
            if hit is not None:
                return hit
            time.sleep(0.005)
        raise SystemExit(f"no output of SHIFT {value} within {timeout}s")

    def source_gap_periods(self, since_wall: float) -> tuple[float, int]:
        """The longest pause of ``source/out`` since ``since_wall`` (stamps), in periods, and messages lost."""
        with self.lock:
            rows = [(seq, stamp) for seq, stamp in self.source if stamp >= since_wall]
        lost = rows[-1][0] - rows[0][0] + 1 - len(rows)
        return max(b[1] - a[1] for a, b in zip(rows, rows[1:])) * RATE_HZ, lost

    def close(self) -> None:
        for sub in self.subs:
            sub.undeclare()
        self.session.close()


def start(folder: Path, env: dict[str, str], *extra: str) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "handflow.framework.cli", "run", "g.yaml", *extra]
    return subprocess.Popen(cmd, cwd=folder, env=env, stderr=subprocess.DEVNULL)


def stop(run: subprocess.Popen) -> None:
    run.send_signal(signal.SIGINT)
    run.wait(timeout=60)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--edits", type=int, default=10)
    ap.add_argument("--restarts", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        plugin = folder / "tempshift.py"
        plugin.write_text(PLUGIN.format(shift=0.0))
        os.environ["HANDFLOW_RUN_DIR"] = tmp  # this run's graphs only, for discovery here and in the launcher
        env = register_plugins(folder, "tempshift", {"temp.shift": "tempshift:Shift"})
        name = f"watchbench{time.monotonic_ns() % 10**8}"
        (folder / "g.yaml").write_text(GRAPH.format(name=name))

        run = start(folder, env, "--watch")
        while not live_runs():
            time.sleep(0.1)
        stream = Stream(name)
        stream.first_shift_at_least(0.0, 0.0)
        time.sleep(2.0)
        reloads, gaps, lost = [], [], 0
        for k in range(1, args.edits + 1):
            edited, edited_wall = time.monotonic(), time.time()
            plugin.write_text(PLUGIN.format(shift=100.0 * k))
            reloads.append(stream.first_shift_at_least(100.0 * k - 50, edited) - edited)
            time.sleep(1.0)  # the source's stream after the reload, for its gap
            gap, n = stream.source_gap_periods(edited_wall)
            gaps.append(gap)
            lost += n
            print(f"edit {k}: new output after {reloads[-1]:.2f} s; source gap {gap:.1f} periods", file=sys.stderr)

        restarts = []
        for _ in range(args.restarts):  # without --watch: stop the graph and run it again
            stopped = time.monotonic()
            stop(run)
            stream.close()
            run = start(folder, env)
            while not live_runs():
                time.sleep(0.02)
            stream = Stream(name)
            restarts.append(stream.first_shift_at_least(0.0, stopped) - stopped)
            print(f"stop and run again: first output after {restarts[-1]:.2f} s", file=sys.stderr)
        stream.close()
        stop(run)

    result = {
        "edits": args.edits,
        "reload_s_median": round(statistics.median(reloads), 3),
        "reload_s_max": round(max(reloads), 3),
        "gap_periods_max": round(max(gaps), 2),
        "source_lost": lost,
        "restart_s_median": round(statistics.median(restarts), 3),
        "ratio_reload_vs_restart": round(statistics.median(reloads) / statistics.median(restarts), 3),
        "goal_reload_s": 2.0,
        "goal_gap_periods": 3.0,
    }
    print(json.dumps(result, indent=2) if args.json else result)


if __name__ == "__main__":
    main()
