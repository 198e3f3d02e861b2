"""The cost of `handflow evaluate segmentation` on continuous recordings (docs/benchmarks.md,
"Evaluation speed"), two figures:

- ``jobs``: the whole evaluation run as a user runs it, ``--jobs 1`` (the baseline: the folds one
  after the other, as before) and ``--jobs N`` alternately ``--repeats`` times in this run; prints
  the median wall times, their ratio and whether the JSON (all but ``runtime_s``) is identical
  (exit code 1 otherwise);
- ``scaling``: BasicMotions made continuous from ``--cases`` cases drawn with replacement
  (``basicmotions-continuous --cases N``), one fold (the first recording held out) with the
  default command's views (every normalisation and derived-feature choice, ``--quick``) timed
  per method on one core, each size in a process of its own; prints per size the seconds per
  method, the process's peak RSS and each method's open-set accuracy on the held-out recording,
  and each method's exponent, the least-squares slope of log seconds over log cases.

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
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from evaluation_fold import timed_fold

from handflow.plugins.segmenter.datasets import basicmotions_continuous, load_recordings
from handflow.plugins.segmenter.evaluation import NORMALISATIONS, default_jobs, frame_metrics
from handflow.plugins.segmenter.features import DERIVED


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


def one_size(path: Path, methods: tuple[str, ...]) -> dict:
    """The first fold of the recordings at ``path`` with the default command's views: seconds and
    open-set accuracy per method and this process's peak RSS (run in a process of its own)."""
    data = load_recordings(path)
    took, fold = timed_fold(data, data.names()[0], methods, quick=True, normalise=NORMALISATIONS, derived=DERIVED)
    known = list(range(len(data.class_names)))
    return {
        "seconds": took,
        "accuracy": {m: frame_metrics(fold.truth, fold.labels[m], known)["open_set_accuracy"] for m in methods},
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "frames": sum(len(r.y) for r in data.recordings),
    }


def scaling_figure(args) -> dict:
    methods = tuple(args.methods.split(","))
    cases = [int(n) for n in args.cases.split(",")]
    sizes = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in cases:
            path = Path(tmp) / f"bm{n}.npz"
            np.savez(path, **basicmotions_continuous(args.recordings, cases=n))
            cmd = [sys.executable, __file__, "one-size", str(path), "--methods", ",".join(methods)]
            out = subprocess.run(cmd, capture_output=True, text=True)
            if out.returncode:
                raise SystemExit(f"{n} cases failed:\n{out.stderr[-2000:]}")
            size = json.loads(out.stdout)
            sizes.append(size)
            print(
                f"{n} cases ({size['frames']} frames): "
                + ", ".join(f"{m} {size['seconds'][m]:.1f} s ({size['accuracy'][m]:.3f})" for m in methods)
                + f"; peak RSS {size['peak_rss_mb']:.0f} MB",
                file=sys.stderr,
                flush=True,
            )
    seconds = {m: [size["seconds"][m] for size in sizes] for m in methods}
    exponents = {
        m: float(np.polyfit(np.log(cases), np.log(s), 1)[0]) if len(cases) > 1 else None for m, s in seconds.items()
    }
    return {
        "cases": cases,
        "seconds": seconds,
        "exponent": exponents,
        "accuracy": {m: [size["accuracy"][m] for size in sizes] for m in methods},
        "peak_rss_mb": [size["peak_rss_mb"] for size in sizes],
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("figure", choices=("jobs", "scaling", "one-size"), help="one-size: scaling's child process")
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
    if args.figure == "one-size":
        print(json.dumps(one_size(args.recordings, tuple(args.methods.split(",")))))
        return 0
    if args.figure == "scaling":
        args.methods = args.methods or "ukr_clm,minirocket"
        result = scaling_figure(args)
        text = (
            "\n".join(
                f"{m}: "
                + ", ".join(f"{n} cases {s:.1f} s" for n, s in zip(result["cases"], result["seconds"][m]))
                + (f"; exponent {result['exponent'][m]:.2f}" if result["exponent"][m] is not None else "")
                for m in result["seconds"]
            )
            + "\npeak RSS: "
            + ", ".join(f"{n} cases {mb:.0f} MB" for n, mb in zip(result["cases"], result["peak_rss_mb"]))
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
