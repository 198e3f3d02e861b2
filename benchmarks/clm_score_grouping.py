"""The CLM as a grouping layer over MiniRocket frame scores on continuous recordings, without
rejection: frame accuracy and segment F1 of MiniRocket alone (argmax of the ridge scores) against
the CLM over the same scores (``score_evidence`` → ``evidence_band`` → CLM, background strength 0)
for several histories H, leave one recording out, the same fitted MiniRocket per fold for both.
MiniRocket window 16 (the one the evaluation selects on BasicMotions).  Metrics as in
``handflow evaluate segmentation`` (docs/segmentation.md).

    python benchmarks/clm_score_grouping.py bm.npz [--folds 0,1,...] [--histories 5,10,20]
"""

from __future__ import annotations

import one_core  # noqa: F401  (one thread for BLAS and numba, set before numpy loads)

# isort: split
import argparse
import time

import numpy as np

from handflow.plugins.segmenter.clm import CLMSegmenter, default_solver
from handflow.plugins.segmenter.compatibility import evidence_band, score_evidence
from handflow.plugins.segmenter.datasets import load_recordings, segments
from handflow.plugins.segmenter.evaluation import MiniRocketMethod, frame_metrics, segment_f1
from handflow.plugins.segmenter.evaluation._recordings import _zscore


def clm_labels(scores: np.ndarray, classes: np.ndarray, history: int) -> np.ndarray:
    seg = CLMSegmenter(history=history, background_factor=0.0, solver=default_solver(max_sweeps=300), random_state=0)
    _, _, width = seg.widths()
    local = seg.fit_predict_bands(*seg.with_background(evidence_band(score_evidence(scores), width, history)))
    return np.where(local >= 0, classes[np.maximum(local, 0)], -1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset")
    ap.add_argument("--folds", default=None, help="comma-separated recording indices held out (default all)")
    ap.add_argument("--histories", default="5,10,20")
    args = ap.parse_args()
    data = load_recordings(args.dataset)
    known = list(range(len(data.class_names)))
    folds = [int(a) for a in args.folds.split(",")] if args.folds else range(len(data.recordings))
    histories = [int(h) for h in args.histories.split(",")]
    method, pairs = MiniRocketMethod(), {}
    for k in folds:
        held = data.recordings[k].name
        train = data.without(held)
        by_name = {r.name: r for r in _zscore(train, data.recordings)}
        test = by_name[held]
        t0 = time.perf_counter()
        fitted = method.fit(segments([by_name[r.name] for r in train], known), {"window": 16}, 0)
        scores = method.prepare(fitted, test.X)
        classes = np.asarray(fitted.classes)
        pairs.setdefault("minirocket", []).append((test.y, classes[scores.argmax(axis=1)]))
        for h in histories:
            pairs.setdefault(f"clm_minirocket H={h}", []).append((test.y, clm_labels(scores, classes, h)))
        print(f"fold {held}: {time.perf_counter() - t0:.0f} s", flush=True)
    for name, p in pairs.items():
        truth, pred = np.concatenate([t for t, _ in p]), np.concatenate([q for _, q in p])
        acc = frame_metrics(truth, pred, known)["known_accuracy"]
        print(
            f"{name:22s} frame accuracy {acc:.3f}  rejected {np.mean(pred == -1):.3f}  segment_f1 {segment_f1(p, known):.3f}"
        )


if __name__ == "__main__":
    main()
