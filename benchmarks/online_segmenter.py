"""Online UKR/CLM segmenter: per-sample latency (projection / CLM split), label revisions per
minute, accuracy on arrival and of the final labels, agreement of the final published online labels
with the whole-stream batch UKR/CLM.  Latency is wall time per sample; ``cpu_ms_*`` is the
thread's CPU time per sample (``time.thread_time``), the cost on one core even when other jobs
share the machine.

``--classes`` candidate manifolds (default 4; 16 = all real letters) + background, sliding window
200, a stream "recorded" at 100 Hz (letters of those classes one after another, so the stream
holds transitions).  Every sample is processed exactly as the node does (batched projection onto
all manifolds, the fast CLM run over the newest observations, the block runs that fix the final
labels; docs/segmentation.md §C).  Baselines in the same run: the fast run over the whole window
instead of its tail (``tail=None``, same sweep budget); the per-model projection (one
``StructuredUKR.transform`` per candidate, the path before the batched projector); and
revisions counted the old way (every change of an earlier label, ``confirm=1``, ``edge=0``).
BLAS is limited to one thread (one core); numba code is single-threaded.

    python benchmarks/online_segmenter.py [--seconds 20] [--dataset letters.npz] [--classes 16] [--json]
        [--reconstruction absolute|relative] [--delay 8] [--background-factor F] [--headings 0,1]

``--reconstruction relative`` uses the class models for real recordings
(:func:`handflow.plugins.segmenter.models.fit_recording_models`: delay embedding, relative
evidence with a null-model background; docs/segmentation.md) instead of the thesis' models; each
sample is then embedded sample by sample as the node does.  ``--headings 0,1`` gives the thesis'
models the heading channels of columns 0 and 1 (docs/segmentation.md); each sample is then headed
sample by sample, and projected a second time with its heading turned round, as the node does.
"""

from __future__ import annotations

import one_core  # noqa: F401  (one thread for BLAS and numba, set before numpy loads)

# isort: split
import argparse
import json
import os
import sys
import time

import numpy as np

from handflow.plugins.segmenter import (
    CLMSegmenter,
    LetterGenerator,
    OnlineCLMSegmenter,
    candidate_set,
    load_dataset,
    train_class_models,
)
from handflow.plugins.segmenter.models import fit_recording_models

RATE_HZ = 100.0


def make_stream(args):
    if args.dataset:
        ds = load_dataset(args.dataset)
        ds = ds.restrict(ds.classes[: args.classes])
    else:
        ds = LetterGenerator(n_classes=args.classes, random_state=args.seed, noise=0.01).dataset((5, 5, 5))
    if args.reconstruction == "relative":
        by_class = {c: [t.data for t in ts] for c, ts in ds.by_class("train").items()}
        cands = fit_recording_models(by_class, delay=args.delay, random_state=args.seed, scaling="standard")
    else:
        headings = tuple(int(c) for c in args.headings.split(",") if c)
        cands = candidate_set(train_class_models(ds, n_steps=200, random_state=args.seed, headings=headings))
    pool = ds.test + ds.validation
    rng = np.random.default_rng(args.seed)
    parts, truth, n = [], [], int(args.seconds * RATE_HZ)
    while sum(map(len, parts)) < n:
        t = pool[rng.integers(len(pool))]
        parts.append(t.data)
        truth.append(np.full(len(t.data), cands.classes.index(t.label)))
    return cands, np.vstack(parts)[:n], np.concatenate(truth)[:n]


def per_model_projection_ms(cands, Y):
    """Baseline: single-point projection with one ``transform`` per candidate (median, p99 in ms)."""
    t = []
    for y in cands.headings.transform(Y):  # headed rows (heading channels, if any)
        t0 = time.perf_counter()
        for m in cands.models.values():
            m.project(y[None])
        t.append(time.perf_counter() - t0)
    t = np.array(t[50:]) * 1e3
    return float(np.median(t)), float(np.percentile(t, 99))


def run(cands, Y, truth, seed: int, confirm: int = 5, edge=None, **params):
    seg = OnlineCLMSegmenter(cands, window=200, confirm=confirm, edge=edge, random_state=seed, **params)
    stream = cands.stream()
    lat, cpu, sweeps, revisions, proj_t, clm_t, arrival = [], [], [], 0, [], [], []
    to_truth = from_truth = 0
    final = np.empty(len(Y), dtype=int)
    for y in Y:
        c0 = time.thread_time()
        t0 = time.perf_counter()
        p = stream.project(y)
        t1 = time.perf_counter()
        up = seg.update_projected(*p.row())
        t2 = time.perf_counter()
        cpu.append(time.thread_time() - c0)
        lat.append(t2 - t0)
        proj_t.append(t1 - t0)
        clm_t.append(t2 - t1)
        sweeps.append(up.sweeps)
        arrival.append(up.label)
        final[up.index] = up.label
        for e in up.events:
            if e.kind == "revision":
                revisions += 1
                to_truth += int(np.sum(truth[e.start : e.end + 1] == e.label))
                from_truth += int(np.sum(truth[e.start : e.end + 1] == e.previous))
                final[e.start : e.end + 1] = e.label
    for e in seg.finish():
        if e.kind == "revision":
            final[e.start : e.end + 1] = e.label
    ms = {
        k: np.array(v[50:]) * 1e3 for k, v in (("latency", lat), ("cpu", cpu), ("projection", proj_t), ("clm", clm_t))
    }
    out = {
        f"{k}_ms_{q}": float(np.percentile(v, 50 if q == "median" else 99))
        for k, v in ms.items()
        for q in ("median", "p99")
    }
    return {
        **out,
        "sweeps_median": float(np.median(sweeps[50:])),
        "revisions_per_min": revisions / (len(Y) / RATE_HZ / 60.0),
        "revised_points_to_truth": to_truth,
        "revised_points_from_truth": from_truth,
        "accuracy_on_arrival": float(np.mean(np.array(arrival) == truth)),
        "accuracy_final": float(np.mean(final == truth)),
        "final": final,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0, help="stream length in seconds at 100 Hz")
    ap.add_argument("--dataset", help="labelled dataset (its first --classes classes); default synthetic letters")
    ap.add_argument("--classes", type=int, default=4, help="number of candidate manifolds (16 = all real letters)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--reconstruction", choices=("absolute", "relative"), default="absolute")
    ap.add_argument("--delay", type=int, default=8, help="delay window of the relative models (frames)")
    ap.add_argument("--history", type=int, default=10, help="CLM neighbourhood H")
    ap.add_argument(
        "--background-factor", type=float, help="background factor (default 1; 0.25 with --reconstruction relative)"
    )
    ap.add_argument("--min-span", type=int, default=0, help="CLM neighbourhood of at least this many observations")
    ap.add_argument(
        "--min-progress", type=float, default=0.0, help="reject final segments below this share of a period"
    )
    ap.add_argument(
        "--max-fit-ratio",
        type=float,
        help="reject final segments whose model fits them worse than this many times the best one",
    )
    ap.add_argument("--block", type=int, help="observations finalised per block run (default window/2)")
    ap.add_argument("--headings", default="", help="channel indices whose heading the thesis models add (e.g. 0,1)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    cands, Y, truth = make_stream(args)
    factor = args.background_factor
    factor = (0.25 if args.reconstruction == "relative" else 1.0) if factor is None else factor
    clm = {
        "history": args.history,
        "reconstruction": args.reconstruction,
        "background_factor": factor,
        "min_span": args.min_span,
        "min_progress": args.min_progress,
        "max_fit_ratio": args.max_fit_ratio,
    }
    run(cands, Y[:60], truth[:60], args.seed, **clm)  # compile numba kernels outside the measurement
    load = os.getloadavg()[0]
    online = run(cands, Y, truth, args.seed, block=args.block, **clm)
    whole = run(cands, Y, truth, args.seed, tail=None, **clm)
    every_change = run(cands, Y, truth, args.seed, confirm=1, edge=0, **clm)
    base_med, base_p99 = per_model_projection_ms(cands, Y[:500]) if args.reconstruction == "absolute" else (None, None)
    batch = CLMSegmenter(cands, random_state=args.seed, **clm).fit_predict(Y)
    out = {
        **{k: v for k, v in online.items() if k != "final"},
        "online_batch_agreement": float(np.mean(online["final"] == batch)),
        "batch_accuracy": float(np.mean(batch == truth)),
        "revisions_per_min_every_change": every_change["revisions_per_min"],
        **{
            f"{k}_every_change": every_change[k]
            for k in ("revised_points_to_truth", "revised_points_from_truth", "accuracy_final")
        },
        **{
            f"whole_window_{k}": whole[k]
            for k in ("latency_ms_median", "latency_ms_p99", "clm_ms_median", "clm_ms_p99", "accuracy_on_arrival")
        },
        "clm_ratio_tail_vs_whole_window": online["clm_ms_median"] / whole["clm_ms_median"],
        "per_model_projection_ms_median": base_med,
        "per_model_projection_ms_p99": base_p99,
        "projection_speedup_median": base_med / online["projection_ms_median"] if base_med else None,
        "samples": int(len(Y)),
        "candidates": len(cands),
        "window": 200,
        "block": args.block,
        **clm,
        "rate_hz": RATE_HZ,
        "data": args.dataset or "synthetic letters",
        "load_average_1min": [load, os.getloadavg()[0]],
        "goal_p99_ms": 10.0,
    }
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        for k, v in out.items():
            print(f"{k:28s} {v:.3f}" if isinstance(v, float) else f"{k:28s} {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
