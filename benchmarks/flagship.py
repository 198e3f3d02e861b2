"""The flagship on this machine: start-up, CPU use, latency glove frame → segment label.

    python benchmarks/flagship.py [--json] [--seconds 20] [--fresh-install]

- **start-up**: ``handflow run configs/demo.yaml --record`` from the command to the first label
  (first ``segmenter/labels`` message's receive time in the recording); ``--fresh-install`` also
  times the README's set-up in a fresh ``python -m venv`` on a copy of the working tree
  (``pip install -e .`` with this machine's pip configuration) and the same start-up there.
- **CPU**: per process (launcher and every node process) and total, from ``/proc/<pid>/stat``
  over ``--seconds`` of steady running after the first label; baseline in the same run: the bare
  glove chain ``configs/glove_emulated.yaml`` (glove → human → shadow → sink) over the same time.
- **latency** (median / p99, ms): receive time in the recording (the launcher's recorder) minus the
  header stamp (the glove frame's arrival time, kept by the mapping nodes and the segmenter), for
  ``segmenter/labels``; baselines from the same run: ``glove/frames`` (bare glove → recorder) and
  ``shadow/joints`` (after the two mapping hops).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from procs import cpu_s, descendants, unit_name

REPO = Path(__file__).resolve().parents[1]


def _labels_seen(rec: Path) -> bool:
    import logging

    from handflow.framework.files.mcap_reader import iter_recording

    logging.getLogger("handflow.recording").setLevel(logging.ERROR)  # the file is still being written
    try:
        return any(rm.topic.endswith("/segmenter/labels") for rm in iter_recording(rec))
    except Exception:
        return False


def run_graph(graph: str, seconds: float, rec: Path, handflow: list[str], cwd: Path, wait_label: bool) -> dict:
    """Run ``graph``; CPU per process over ``seconds`` of steady running; the recording for latencies."""
    t0 = time.time_ns()
    proc = subprocess.Popen(
        [*handflow, "run", graph, "--record", str(rec)], cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        deadline = time.monotonic() + 180
        while wait_label and not (rec.exists() and _labels_seen(rec)):
            if time.monotonic() > deadline or proc.poll() is not None:
                raise RuntimeError(f"{graph}: no label within 180 s")
            time.sleep(0.5)
        time.sleep(3.0 if wait_label else 8.0)  # settle (numba JIT, first images)
        pids = [proc.pid, *descendants(proc.pid)]
        start = {p: cpu_s(p) for p in pids}
        t_start = time.monotonic()
        time.sleep(seconds)
        elapsed = time.monotonic() - t_start
        cpu = {}
        for p in pids:
            a, b = start[p], cpu_s(p)
            if a is not None and b is not None:
                cpu[unit_name(p)] = round(100 * (b - a) / elapsed, 1)
    finally:
        proc.send_signal(2)
        proc.wait(timeout=60)
    return {"t0_ns": t0, "cpu_percent": cpu, "cpu_percent_total": round(sum(cpu.values()), 1)}


def latencies(rec: Path, t0_ns: int, settle_s: float = 3.0) -> dict:
    """First-label time, and latencies of the messages stamped ``settle_s`` after the first label
    (the start-up backlog of the glove reader is not steady-state latency)."""
    from handflow.framework.files.mcap_reader import iter_recording

    messages = [("/".join(rm.topic.split("/")[2:]), rm.log_time_ns, rm.publish_time_ns) for rm in iter_recording(rec)]
    first_label = next((log for port, log, _ in messages if port == "segmenter/labels"), None)
    steady = (first_label or 0) + int(settle_s * 1e9)
    lat: dict[str, list[float]] = {}
    for port, log, stamp in messages:
        if stamp >= steady and port in ("glove/frames", "shadow/joints", "segmenter/labels"):
            lat.setdefault(port, []).append((log - stamp) / 1e6)
    out = {"first_label_s": None if first_label is None else round((first_label - t0_ns) / 1e9, 2)}
    for port, key in (("segmenter/labels", "label"), ("glove/frames", "baseline_glove"), ("shadow/joints", "mapped")):
        v = np.array(lat.get(port, [np.nan]))
        out[f"{key}_latency_ms"] = [round(float(np.median(v)), 2), round(float(np.percentile(v, 99)), 2)]
        out[f"{key}_count"] = int(np.isfinite(v).sum())
    return out


def fresh_install(tmp: Path) -> dict:
    """The README's first command in a fresh venv on a copy of the working tree (timed in two parts)."""
    tree = tmp / "handflow"
    shutil.copytree(REPO, tree, ignore=shutil.ignore_patterns(".git", "out", "__pycache__", "*.egg-info", ".venv"))
    t = time.monotonic()
    subprocess.run([sys.executable, "-m", "venv", str(tmp / "venv")], check=True)
    venv_s = time.monotonic() - t
    t = time.monotonic()
    subprocess.run([str(tmp / "venv" / "bin" / "pip"), "install", "-q", "-e", "."], cwd=tree, check=True)
    pip_s = time.monotonic() - t
    rec = tree / "out" / "demo_fresh.mcap"
    res = run_graph("configs/demo.yaml", 2.0, rec, [str(tmp / "venv" / "bin" / "handflow")], tree, True)
    return {
        "venv_s": round(venv_s, 1),
        "pip_install_s": round(pip_s, 1),
        "first_label_s": latencies(rec, res["t0_ns"])["first_label_s"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--seconds", type=float, default=20.0, help="CPU measurement window")
    ap.add_argument("--fresh-install", action="store_true", help="also time a fresh venv + pip install -e .")
    args = ap.parse_args()
    handflow = [sys.executable, "-m", "handflow.framework.cli"]
    with tempfile.TemporaryDirectory(prefix="handflow-bench-") as d:
        tmp = Path(d)
        flag = run_graph("configs/demo.yaml", args.seconds, tmp / "demo.mcap", handflow, REPO, True)
        base = run_graph("configs/glove_emulated.yaml", args.seconds, tmp / "glove.mcap", handflow, REPO, False)
        lat = latencies(tmp / "demo.mcap", flag["t0_ns"])
        result = {
            "startup_first_label_s": lat.pop("first_label_s"),
            "cpu_percent_total": flag["cpu_percent_total"],
            "cpu_percent": flag["cpu_percent"],
            "baseline_glove_chain_cpu_percent_total": base["cpu_percent_total"],
            "baseline_glove_chain_cpu_percent": base["cpu_percent"],
            "cpu_ratio_to_glove_chain": round(flag["cpu_percent_total"] / max(base["cpu_percent_total"], 1e-9), 2),
            **lat,
            "label_latency_ratio_to_glove": round(
                lat["label_latency_ms"][0] / max(lat["baseline_glove_latency_ms"][0], 1e-9), 1
            ),
            "cpu_seconds": args.seconds,
            "cores": os.cpu_count(),
        }
        if args.fresh_install:
            result["fresh_install"] = fresh_install(tmp)
    if args.json:
        print(json.dumps(result))
    else:
        for k, v in result.items():
            print(f"{k:42s} {v}")


if __name__ == "__main__":
    main()
