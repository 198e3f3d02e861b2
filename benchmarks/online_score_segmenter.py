"""Online CLM over a MiniRocket scorer (the ``segmenter.online_clm`` node with ``source: minirocket``):
per-sample latency including the scorer, and agreement of the final published online labels with
the whole-recording batch CLM over the same evidence.

Continuous recordings (e.g. BasicMotions made continuous: ``handflow basicmotions-continuous
basicmotions.npz --out bm.npz``).  For each of the first ``--folds`` recordings: a MiniRocket
scorer (window ``--window``) is fitted on the labelled segments of the others, saved and reloaded
(the node's path), and the held-out recording is fed sample by sample through
``OnlineScoreCLMSegmenter.update`` (score the causal window + warm-started CLM over the sliding
window of 200, 100 Hz).  Baseline in the same run: the scorer alone per sample (MiniRocket
argmax, no CLM).  BLAS and numba are limited to one thread.

    python benchmarks/online_score_segmenter.py bm.npz [--folds 2] [--background 0.5] [--clm-window 200] [--novelty 0.25] [--distance-z 2] [--null-class] [--json]

``--novelty F`` adds the novelty term (class manifolds with a delay window of 8 fitted on the same
segments; their projection is part of the scorer time); ``--distance-z Z`` the feature novelty
(part of the scorer time too).  ``--null-class`` rejects with the null class instead of the
background factor, its score calibrated on the fold's training recordings as ``fit-scorer`` does
(``evaluation.calibrate_null_score``, untimed; docs/segmentation.md, "Score sources").
"""

from __future__ import annotations

import one_core  # noqa: F401  (one thread for BLAS and numba, set before numpy loads)

# isort: split
import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from handflow.plugins.segmenter.datasets import RecordingSet, load_recordings, segments
from handflow.plugins.segmenter.evaluation import calibrate_null_score
from handflow.plugins.segmenter.models import fit_recording_models
from handflow.plugins.segmenter.online import OnlineScoreCLMSegmenter, batch_labels
from handflow.plugins.segmenter.scorers import MiniRocketScorer, load_scorer

WARMUP = 50  # samples skipped in the latency figures (JIT, filling the window)


def stream(seg: OnlineScoreCLMSegmenter, X: np.ndarray) -> dict:
    """Feed X sample by sample; per-sample times of the scorer and the CLM, final published labels."""
    seg.reset()
    published = np.full(len(X), -1)
    score_t, clm_t = [], []
    recent: list[np.ndarray] = []
    for x in X:
        t0 = time.perf_counter()
        recent = (recent + [x])[-seg.scorer.window :]
        s, feature_novelty = seg.score_last(np.asarray(recent))
        known = seg.known_weight(x, feature_novelty)
        t1 = time.perf_counter()
        up = seg.update_scores(s, known)
        t2 = time.perf_counter()
        score_t.append(t1 - t0)
        clm_t.append(t2 - t1)
        published[up.index] = up.label
        for ev in up.events:
            if ev.kind == "revision":
                published[ev.start : ev.end + 1] = ev.label
    return {"labels": published, "score_s": np.array(score_t[WARMUP:]), "clm_s": np.array(clm_t[WARMUP:])}


def node_path_latency(seg: OnlineScoreCLMSegmenter, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample wall and CPU (thread) time of ``update(y)`` exactly as the node calls it (input
    check, buffer, scorer, CLM); the CPU time is what the sample costs on a core of its own."""
    seg.reset()
    wall, cpu = [], []
    for x in X:
        t0, c0 = time.perf_counter(), time.thread_time()
        seg.push(x)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.thread_time() - c0)
    return np.array(wall[WARMUP:]), np.array(cpu[WARMUP:])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recordings", help="continuous recordings (.npz or CSV folder)")
    ap.add_argument("--folds", type=int, default=2, help="held-out recordings measured (the first ones)")
    ap.add_argument("--window", type=int, default=32, help="MiniRocket window (frames)")
    ap.add_argument("--background", type=float, default=0.5, help="background factor (× λ_bg)")
    ap.add_argument("--history", type=int, default=10)
    ap.add_argument("--clm-window", type=int, default=200, help="observations in the CLM's sliding window")
    ap.add_argument(
        "--novelty",
        type=float,
        default=None,
        help="add the novelty term: class manifolds (delay 8) fitted on the same segments, this novelty factor",
    )
    ap.add_argument("--distance-z", type=float, default=None, help="add the feature novelty beyond this z-score")
    ap.add_argument(
        "--null-class",
        action="store_true",
        help="reject with the null class, its score calibrated on the training recordings (not --background)",
    )
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    data = load_recordings(args.recordings)
    classes = list(range(len(data.class_names)))
    cpu, lat, score_ms, clm_ms, base_ms, agree, acc_on, acc_batch, acc_mr, n, nk = (
        [],
        [],
        [],
        [],
        [],
        [],
        [],
        [],
        [],
        0,
        0,
    )
    params = dict(history=args.history, background_factor=args.background, distance_z=args.distance_z, random_state=0)
    null_scores = []
    for rec in data.recordings[: args.folds]:
        segs = segments(data.without(rec.name), classes)
        scorer = MiniRocketScorer(window=args.window, random_state=0).fit(
            {data.class_names[c]: segs[c] for c in classes}
        )
        with tempfile.TemporaryDirectory() as tmp:
            scorer = load_scorer(scorer.save(Path(tmp) / "scorer.npz"))
        if args.novelty is not None:
            by_name = {data.class_names[c]: segs[c] for c in classes}
            params.update(novelty_models=fit_recording_models(by_name, delay=8, random_state=0), novelty=args.novelty)
        if args.null_class:
            training = RecordingSet(data.without(rec.name), data.class_names, data.columns, data.source)
            null_scores.append(float(calibrate_null_score(training, "minirocket", args.window).reject))
            params["null_score"] = null_scores[-1]
            print(f"{rec.name}: null score {null_scores[-1]:.4g}", file=sys.stderr)
        seg = OnlineScoreCLMSegmenter(scorer, window=args.clm_window, **params)
        node_path_latency(seg, rec.X[: WARMUP + 10])  # compile numba kernels outside the measurement
        run = stream(seg, rec.X)
        wall, thread = node_path_latency(seg, rec.X)
        lat.append(wall)
        cpu.append(thread)
        score_ms.append(run["score_s"])
        clm_ms.append(run["clm_s"])
        t = []
        for i in range(len(rec.X)):  # baseline: the scorer alone, argmax per sample
            t0 = time.perf_counter()
            scorer.scores_last(rec.X[max(0, i - args.window + 1) : i + 1]).argmax()
            t.append(time.perf_counter() - t0)
        base_ms.append(np.array(t[WARMUP:]))
        batch = batch_labels(scorer, rec.X, **params)
        known = rec.y >= 0
        agree.append(np.sum(run["labels"] == batch))
        acc_on.append(np.sum((run["labels"] == rec.y)[known]))
        acc_batch.append(np.sum((batch == rec.y)[known]))
        acc_mr.append(np.sum((scorer.scores(rec.X).argmax(axis=1) == rec.y)[known]))
        n += len(rec.X)
        nk += int(known.sum())
        print(f"{rec.name}: agreement {agree[-1] / len(rec.X):.3f}", file=sys.stderr)
    lat_ms, base = np.concatenate(lat) * 1e3, np.concatenate(base_ms) * 1e3
    out = {
        "latency_ms_median": float(np.median(lat_ms)),
        "latency_ms_p99": float(np.percentile(lat_ms, 99)),
        "cpu_ms_median": float(np.median(np.concatenate(cpu)) * 1e3),
        "cpu_ms_p99": float(np.percentile(np.concatenate(cpu), 99) * 1e3),
        "scorer_ms_median": float(np.median(np.concatenate(score_ms)) * 1e3),
        "scorer_ms_p99": float(np.percentile(np.concatenate(score_ms), 99) * 1e3),
        "clm_ms_median": float(np.median(np.concatenate(clm_ms)) * 1e3),
        "clm_ms_p99": float(np.percentile(np.concatenate(clm_ms), 99) * 1e3),
        "scorer_alone_ms_median": float(np.median(base)),
        "scorer_alone_ms_p99": float(np.percentile(base, 99)),
        "latency_ratio_vs_scorer_alone": float(np.median(lat_ms) / np.median(base)),
        "online_batch_agreement": float(np.sum(agree) / n),
        "accuracy_online": float(np.sum(acc_on) / nk),
        "accuracy_batch_clm": float(np.sum(acc_batch) / nk),
        "accuracy_minirocket_argmax": float(np.sum(acc_mr) / nk),
        "samples": n,
        "held_out": data.names()[: args.folds],
        "window": args.clm_window,
        "minirocket_window": args.window,
        "background_factor": None if args.null_class else args.background,
        "null_scores": null_scores or None,
        "history": args.history,
        "novelty": args.novelty,
        "distance_z": args.distance_z,
        "goal_p99_ms": 10.0,
        "goal_agreement": 0.98,
    }
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        for k, v in out.items():
            print(f"{k:32s} {v:.3f}" if isinstance(v, float) else f"{k:32s} {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
