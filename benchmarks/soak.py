"""Soak: the flagship (emulated glove, mapping, simulated hand with camera, segmenter, recorder) for
a long time — memory, loss, latency drift and restarts (docs/reliability.md).

    python benchmarks/soak.py [--duration 3600] [--window 300] [--json]

- ``rss_growth_max``: largest per-process fraction ``(last RSS − RSS after warm-up) / RSS after
  warm-up`` (RSS sampled every ``--sample`` s; warm-up = the first window); ``rss_anon_growth_max``
  the same for the anonymous part of the RSS (the heap, where a leak shows; the rest is mapped
  files, which a process forked from the zygote maps on first use);
- ``lost_messages``: gaps in the sequence numbers of every recorded topic (what the recorder did
  not get, restarts included) plus the input gaps the nodes themselves counted;
- ``p99_ms_first_window`` / ``p99_ms_last_window``: latency of ``segmenter/labels`` (receive time at
  the recorder − the glove frame's arrival stamp) in the first and the last window, counted from
  10 s after the first label; the same for every window under ``windows``;
- ``restarts``: node restarts seen by the launcher.
"""

from __future__ import annotations

import argparse
import json
import signal
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
from procs import descendants, memory_mb, unit_name

LABELS = "segmenter/labels"
SETTLE_S = 10.0  # latency windows start this long after the first label


def _port(topic: str) -> str:
    return "/".join(topic.split("/")[2:])


def run(duration: float, window: float, sample: float, graph: str, workdir: Path) -> dict:
    rec, summary = workdir / "soak.mcap", workdir / "summary.json"
    cmd = [sys.executable, "-m", "handflow.framework.cli", "--log-level", "WARNING", "run", graph]
    cmd += ["--record", str(rec), "--summary-json", str(summary), "--duration", str(duration)]
    proc = subprocess.Popen(cmd, cwd=workdir, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    rss: dict[str, list[tuple[float, float, float]]] = defaultdict(list)  # (t, RSS, anonymous RSS)
    t0 = time.monotonic()
    try:
        while proc.poll() is None:
            now = time.monotonic() - t0
            for pid in [proc.pid, *descendants(proc.pid)]:
                mb = memory_mb(pid)
                if mb is not None:
                    rss[unit_name(pid)].append((now, *mb))
            time.sleep(sample)
    except KeyboardInterrupt:
        proc.send_signal(signal.SIGINT)
    err = proc.communicate(timeout=120)[1]
    if proc.returncode != 0:
        raise SystemExit(f"the flagship exited {proc.returncode}:\n{err[-3000:]}")
    return {"rss": rss, "recording": rec, "summary": json.loads(summary.read_text())}


def analyse(rss: dict, recording: Path, summary: dict, window: float) -> dict:
    from handflow.framework.files.mcap_reader import iter_recording

    seqs: dict[str, list[int]] = defaultdict(list)
    labels: list[tuple[int, int]] = []  # (log time, stamp)
    for rm in iter_recording(recording):
        seqs[rm.topic].append(rm.sequence)
        if _port(rm.topic) == LABELS:
            labels.append((rm.log_time_ns, rm.publish_time_ns))
    lost_recorded = {_port(t): int(np.sum(np.clip(np.diff(sorted(s)) - 1, 0, None))) for t, s in seqs.items()}
    counted = {nid: g for unit in summary.values() for nid, g in unit["gaps"].items()}
    restarts = sum(unit["restarts"] for unit in summary.values())

    log = np.array([t for t, _ in labels], dtype=np.int64)
    lat_ms = np.array([(t - s) / 1e6 for t, s in labels])
    windows = []
    if len(log):
        start = log[0] + int(SETTLE_S * 1e9)  # the start-up backlog is not steady-state latency
        edges = np.arange(start, log[-1] + 1, int(window * 1e9))
        for a in edges:
            sel = (log >= a) & (log < a + int(window * 1e9))
            if sel.sum() >= 20:
                v = lat_ms[sel]
                windows.append({"start_s": round((a - start) / 1e9), "p50_ms": float(np.median(v)), "p99_ms": float(np.percentile(v, 99)), "n": int(sel.sum())})  # fmt: skip

    growth = {}
    for name, samples in rss.items():
        t, mb, anon = np.array(samples).T
        after, anon_after = mb[t >= window], anon[t >= window]
        if len(after) >= 2:
            growth[name] = {
                "rss_mb_after_warmup": float(after[0]),
                "rss_mb_last": float(after[-1]),
                "growth": float(after[-1] / after[0] - 1),
                "anon_mb_after_warmup": float(anon_after[0]),
                "anon_mb_last": float(anon_after[-1]),
                "anon_growth": float(anon_after[-1] / anon_after[0] - 1),
            }
    return {
        "lost_messages": int(sum(lost_recorded.values()) + sum(counted.values())),
        "lost_in_recording_by_topic": {k: v for k, v in lost_recorded.items() if v},
        "input_gaps_counted_by_nodes": {k: v for k, v in counted.items() if v},
        "restarts": int(restarts),
        "rss_growth_max": max((g["growth"] for g in growth.values()), default=None),
        "rss_anon_growth_max": max((g["anon_growth"] for g in growth.values()), default=None),
        "rss": growth,
        "p99_ms_first_window": windows[0]["p99_ms"] if windows else None,
        "p99_ms_last_window": windows[-1]["p99_ms"] if windows else None,
        "windows": windows,
        "recorded_messages": int(sum(map(len, seqs.values()))),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=3600.0, help="seconds of running after every node is ready")
    ap.add_argument("--window", type=float, help="latency window in s (default 300, or duration/3 if shorter)")
    ap.add_argument("--sample", type=float, default=10.0, help="RSS sampling period in s")
    ap.add_argument("--graph", default="demo", help="graph to soak (a shipped name or a path)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    window = args.window or min(300.0, args.duration / 3)
    with tempfile.TemporaryDirectory(prefix="handflow-soak-") as d:
        res = run(args.duration, window, args.sample, args.graph, Path(d))
        out = {"duration_s": args.duration, "window_s": window, **analyse(res["rss"], res["recording"], res["summary"], window)}  # fmt: skip
    if args.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k:28s} {v}")


if __name__ == "__main__":
    main()
