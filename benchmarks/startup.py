"""Launch → first line, ready line and first recorded message of a shipped graph (docs/benchmarks.md,
"Distribution and start-up").

Runs ``handflow run GRAPH --duration D --record FILE`` in a fresh directory several times, notes when
its first line and its "all nodes ready" line arrive (docs/pipelines.md, "Start-up") and reads the
first message's log time from the recording; times are counted from just before the command is
started (the first repeat warms the caches like any earlier run). Baselines, measured in the same run, alternating with it: the same command with node
processes started as fresh interpreters (``HANDFLOW_ZYGOTE=0``, docs/architecture.md, "Process
start-up"), and a bare ``python -c "import numpy, zenoh"`` (what every node process pays at least).

    python benchmarks/startup.py --repeats 5 --json
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from handflow.framework.files.mcap_reader import iter_recording


def first_message_s(graph: str, duration: float, fork: bool = True) -> tuple[float, int, float, float]:
    """Seconds from launch to the first recorded message, the number of recorded messages, and seconds from
    launch to the first line and to the ready line on the terminal."""
    env = {**os.environ, "HANDFLOW_ZYGOTE": "1" if fork else "0"}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run.mcap"
        start_ns = time.time_ns()
        proc = subprocess.Popen(
            ["handflow", "run", graph, "--duration", str(duration), "--record", str(out)],
            cwd=tmp,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        first_line = ready_line = None
        for line in proc.stderr:
            now = (time.time_ns() - start_ns) / 1e9
            first_line = first_line or now
            ready_line = ready_line or (now if "all nodes ready after" in line else None)
        if proc.wait() != 0:
            raise SystemExit(f"handflow run {graph} exited {proc.returncode}")
        times = [m.log_time_ns for m in iter_recording(out)]
    return (min(times) - start_ns) / 1e9, len(times), first_line, ready_line


def bare_import_s() -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import numpy, zenoh"], check=True)
    return time.perf_counter() - start


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--graph", default="demo", help="shipped graph name or path (default: demo)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--duration", type=float, default=2.0, help="seconds each run lasts once every node is ready")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    runs, fresh = [], []
    for i in range(args.repeats):
        runs.append(first_message_s(args.graph, args.duration))
        fresh.append(first_message_s(args.graph, args.duration, fork=False))
        print(
            f"run {i + 1}/{args.repeats}: first line after {runs[-1][2]:.2f} s, ready after {runs[-1][3]:.2f} s, "
            f"first message after {runs[-1][0]:.2f} s (fresh interpreters: {fresh[-1][0]:.2f} s)",
            file=sys.stderr,
        )
    bare = statistics.median(bare_import_s() for _ in range(args.repeats))
    first = statistics.median(r[0] for r in runs)
    first_fresh = statistics.median(r[0] for r in fresh)
    warm = runs[1:] or runs  # the first run after install, or after a while, reads everything from disk
    first_line = statistics.median(r[2] for r in warm)
    result = {
        "graph": args.graph,
        "first_line_s": round(first_line, 3),
        "first_line_s_runs": [round(r[2], 3) for r in runs],
        "first_line_ratio_vs_bare_import": round(first_line / bare, 2),
        "ready_line_s": round(statistics.median(r[3] for r in runs), 3),
        "first_message_s": round(first, 3),
        "first_message_s_runs": [round(r[0], 3) for r in runs],
        "messages_min": min(r[1] for r in runs + fresh),
        "fresh_interpreters_first_message_s": round(first_fresh, 3),
        "ratio_vs_fresh_interpreters": round(first / first_fresh, 2),
        "bare_import_s": round(bare, 3),
        "ratio_vs_bare_import": round(first / bare, 2),
        "load_average_1min": os.getloadavg()[0],
    }
    print(json.dumps(result, indent=2) if args.json else "\n".join(f"{k}: {v}" for k, v in result.items()))


if __name__ == "__main__":
    main()
