"""Parameter round trip on a running graph (docs/benchmarks.md, "Live parameters"; docs/tuning.md).

Runs ``handflow run GRAPH`` and, from a session of its own joined as ``handflow param`` joins,
times ``set`` requests (launcher → node applies under its runtime lock → answer back) of one live
parameter, alternating two values.  Baselines, interleaved in the same run: a ``get`` of the same
parameter (the same path without applying), a ``get`` asked of the node's process directly (no
launcher in between) and the hub's graph-info query (one Zenoh query round trip to the launcher,
the transport's floor).

    python benchmarks/param_roundtrip.py --json
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from handflow.framework.keys import node_params_key, param_request_key
from handflow.framework.network.hub_info import info_key
from handflow.framework.runtime.discovery import join, live_runs

REPO = Path(__file__).resolve().parents[1]


def ask_ms(session, key: str, payload: str | None = None) -> tuple[float, dict]:
    """One query's round trip in ms and its (first) answer."""
    start = time.perf_counter()
    replies = [r.ok.payload.to_bytes() for r in session.get(key, payload=payload, timeout=10.0) if r.ok is not None]
    elapsed = (time.perf_counter() - start) * 1e3
    return elapsed, json.loads(replies[0]) if replies else {}


def figures(ms: list[float]) -> dict[str, float]:
    a = np.asarray(ms)
    return {"p50_ms": round(float(np.median(a)), 2), "p99_ms": round(float(np.percentile(a, 99)), 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--graph", default="configs/demo.yaml", help="graph file to run (default: the demo)")
    ap.add_argument("--param", default="segmenter.background_factor", help="NODE.KEY of a live parameter")
    ap.add_argument("--values", nargs=2, type=float, default=[1.0, 1.5], help="the two values set in turn")
    ap.add_argument("--repeats", type=int, default=300)
    ap.add_argument("--settle", type=float, default=5.0, help="seconds after the graph is ready before timing")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    node, _, key = args.param.partition(".")
    with tempfile.TemporaryDirectory() as runs:
        os.environ["HANDFLOW_RUN_DIR"] = runs
        run = subprocess.Popen(
            [sys.executable, "-m", "handflow.framework.cli", "run", args.graph],
            cwd=REPO,
            stderr=subprocess.DEVNULL,
        )
        try:
            while not live_runs():
                time.sleep(0.1)
            session, info = join()
            graph = info.graph
            set_key, info_k = param_request_key(graph, "local", node), info_key(graph)
            while not ask_ms(session, set_key, json.dumps({"op": "get"}))[1].get("ok"):
                time.sleep(0.2)  # the node is set up
            time.sleep(args.settle)
            sets, gets, direct, infos = [], [], [], []
            for i in range(args.repeats):
                request = {"op": "set", "key": key, "value": args.values[i % 2]}
                ms, answer = ask_ms(session, set_key, json.dumps(request))
                if not answer.get("ok") or answer["params"][key] != args.values[i % 2]:
                    raise SystemExit(f"set refused or not applied: {answer}")
                sets.append(ms)
                gets.append(ask_ms(session, set_key, json.dumps({"op": "get"}))[0])
                direct.append(ask_ms(session, node_params_key(graph, node), json.dumps({"op": "get"}))[0])
                infos.append(ask_ms(session, info_k)[0])
            session.close()
        finally:
            run.terminate()
            run.wait(timeout=60)
    result = {
        "graph": args.graph,
        "param": args.param,
        "repeats": args.repeats,
        "set": figures(sets),
        "get": figures(gets),
        "node_get_without_launcher": figures(direct),
        "hub_query": figures(infos),
        "ratio_set_p99_vs_hub_query_p99": round(float(np.percentile(sets, 99) / np.percentile(infos, 99)), 2),
        "goal_p99_ms": 50.0,
        "load_average_1min": os.getloadavg()[0],
    }
    print(json.dumps(result, indent=2) if args.json else result)


if __name__ == "__main__":
    main()
