"""The cost of `handflow evaluate segmentation` on continuous recordings (docs/benchmarks.md,
"Evaluation speed"), two figures:

- ``jobs``: the whole evaluation run as a user runs it, ``--jobs 1`` (the baseline: the folds one
  after the other, as before) and ``--jobs N`` alternately ``--repeats`` times in this run; prints
  the median wall times, their ratio and whether the JSON (all but ``runtime_s``) is identical
  (exit code 1 otherwise);
- ``scaling``: BasicMotions made continuous from ``--cases`` cases drawn with replacement
  (``basicmotions-continuous --cases N``), one fold (the first recording held out) timed per
  method on one core; prints the seconds per size and each method's exponent, the least-squares
  slope of log seconds over log cases.

    python benchmarks/evaluation_scaling.py jobs bm.npz [--jobs 2] [--methods ...] [--repeats 1]
    python benchmarks/evaluation_scaling.py scaling ../shared/data/basicmotions.npz \
        --cases 80,320,1280 --methods ukr_clm,minirocket [--json]
"""

from __future__ import annotations

import one_core  # (one thread for BLAS and numba, set before numpy loads)

# isort: split
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from evaluation_fold import timed_fold

from handflow.plugins.segmenter.datasets import basicmotions_continuous, load_recordings
from handflow.plugins.segmenter.evaluation import default_jobs


def evaluation(recordings: Path, jobs: int, methods: str | None) -> tuple[float, dict]:
    """Wall seconds and JSON of one `handflow evaluate segmentation --quick` run (BLAS threads as a user has them)."""
    env = {k: v for k, v in os.environ.items() if k not in one_core.SET}
    cmd = ["handflow", "evaluate", "segmentation", str(recordings), "--quick", "--json", "--jobs", str(jobs)]
    start = time.perf_counter()
    out = subprocess.run(cmd + (["--methods", methods] if methods else []), env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if out.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{out.stderr[-2000:]}")
    result = json.loads(out.stdout)
    result.pop("runtime_s"), result.pop("timing")  # wall times: the machine's
    return seconds, result


def jobs_figure(args) -> dict:
    runs: dict[int, list[float]] = {1: [], args.jobs: []}
    results = {}
    for _ in range(args.repeats):
        for jobs in runs:  # alternately, so both see the same load
            seconds, results[jobs] = evaluation(args.recordings, jobs, args.methods)
            runs[jobs].append(seconds)
    baseline, now = float(np.median(runs[1])), float(np.median(runs[args.jobs]))
    return {
        "recordings": str(args.recordings),
        "jobs": args.jobs,
        "seconds": now,
        "baseline_seconds_jobs_1": baseline,
        "ratio": baseline / now,
        "identical_json": results[1] == results[args.jobs],
        "runs": {str(k): v for k, v in runs.items()},
    }


def scaling_figure(args) -> dict:
    methods = tuple(args.methods.split(","))
    cases = [int(n) for n in args.cases.split(",")]
    seconds: dict[str, list[float]] = {m: [] for m in methods}
    with tempfile.TemporaryDirectory() as tmp:
        for n in cases:
            path = Path(tmp) / f"bm{n}.npz"
            np.savez(path, **basicmotions_continuous(args.recordings, cases=n))
            data = load_recordings(path)
            took, _ = timed_fold(data, data.names()[0], methods, quick=True)
            for m in methods:
                seconds[m].append(took[m])
            print(f"{n} cases: " + ", ".join(f"{m} {took[m]:.1f} s" for m in methods), file=sys.stderr, flush=True)
    exponents = {
        m: float(np.polyfit(np.log(cases), np.log(s), 1)[0]) if len(cases) > 1 else None for m, s in seconds.items()
    }
    return {"cases": cases, "seconds": seconds, "exponent": exponents}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("figure", choices=("jobs", "scaling"))
    ap.add_argument("recordings", type=Path, help="jobs: a continuous .npz; scaling: the UEA BasicMotions .npz")
    ap.add_argument("--jobs", type=int, default=default_jobs())
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument(
        "--methods", help="jobs: default all the evaluation's defaults; scaling: default ukr_clm,minirocket"
    )
    ap.add_argument("--cases", default="80,320,1280")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if not args.recordings.exists():
        print(f"{args.recordings} not found (docs/benchmarks.md names the data)", file=sys.stderr)
        return 2
    if args.figure == "scaling":
        args.methods = args.methods or "ukr_clm,minirocket"
        result = scaling_figure(args)
        text = "\n".join(
            f"{m}: "
            + ", ".join(f"{n} cases {s:.1f} s" for n, s in zip(result["cases"], result["seconds"][m]))
            + (f"; exponent {result['exponent'][m]:.2f}" if result["exponent"][m] is not None else "")
            for m in result["seconds"]
        )
    else:
        result = jobs_figure(args)
        text = (
            f"--jobs {args.jobs}: {result['seconds']:.0f} s; --jobs 1 (baseline, same run): "
            f"{result['baseline_seconds_jobs_1']:.0f} s; {result['ratio']:.2f}×; identical JSON: {result['identical_json']}"
        )
    print(json.dumps(result, indent=2) if args.json else text)
    return 0 if result.get("identical_json", True) else 1


if __name__ == "__main__":
    raise SystemExit(main())
