"""Novelty terms for unknown motion over a MiniRocket scorer, probed on one fold with one known class
left out at a time: how well does each term separate the left-out class's frames (unknown) from
the known classes' frames of the held-out recording?

For the held-out recording and each class c in turn: a MiniRocket scorer is fitted on the other
recordings' segments of the remaining classes (c is never seen), then every frame of the
held-out recording gets
- ``max_score``: minus the winning ridge decision value (the thresholded baseline);
- ``margin``: minus the gap between the best and the second-best decision value;
- ``combined``: the larger of a frame's margin and class-distance ranks in their training
  distributions;
- ``class_distance``: the distance of the frame's MiniRocket features (standardised, PCA to 32
  dimensions fitted on the training windows) to the nearest training window *of the predicted
  class*, divided by that class's own spread (the median leave-one-out nearest-neighbour distance
  among its training windows);
- ``feature_novelty``: the scorer's own feature novelty (the term of ``clm_minirocket_novelty``,
  :mod:`handflow.plugins.segmenter.novelty`), a robust z-score; its rejection and known
  frames kept are reported at the limits ``distance_z`` 1 and 2 of the evaluation's grid.
Reported per term: ROC AUC unknown-vs-known (1 = perfect separation, 0.5 = chance) and, at the
threshold where 95 % of the *training* windows count as known (known distance/score quantile),
the unknown-frame rejection and the known frames kept.

    python benchmarks/novelty_probe.py bm.npz [--held-out rec0] [--json]
"""

from __future__ import annotations

import one_core  # noqa: F401  (one thread for BLAS and numba, set before numpy loads)

# isort: split
import argparse
import json
import sys

import numpy as np
from sklearn.metrics import roc_auc_score

from handflow.plugins.segmenter.datasets import load_recordings, segments
from handflow.plugins.segmenter.scorers import WINDOWS_PER_SEGMENT, MiniRocketScorer, causal_windows

PCA_DIMS = 32


def training_windows(scorer: MiniRocketScorer, segs: dict) -> tuple[np.ndarray, np.ndarray]:
    """Features and class index of the scorer's own training windows."""
    F, owner = [], []
    for k, c in enumerate(scorer.classes_):
        for seg in segs[c]:
            ends = np.unique(np.linspace(0, len(seg) - 1, WINDOWS_PER_SEGMENT).astype(int))
            F.append(scorer.features(causal_windows((seg - scorer.mean_) / scorer.std_, ends, scorer.window)))
            owner.append(np.full(len(ends), k))
    return np.vstack(F).astype(float), np.concatenate(owner)


def nearest(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    d = (A * A).sum(1)[:, None] + (B * B).sum(1)[None] - 2 * A @ B.T
    return np.sqrt(np.maximum(d, 0.0))


def probe(data, held: str, left_out: int, window: int) -> dict:
    known = [c for c in range(len(data.class_names)) if c != left_out]
    segs = segments(data.without(held), known)
    scorer = MiniRocketScorer(window=window, random_state=0).fit(segs)
    test = data.get(held)
    S = scorer.scores(test.X)
    F_train, owner = training_windows(scorer, segs)
    mu, sd = F_train.mean(0), F_train.std(0) + 1e-9
    Z = (F_train - mu) / sd
    _, _, Vt = np.linalg.svd(Z - Z.mean(0), full_matrices=False)
    P = Vt[:PCA_DIMS].T
    T = Z @ P
    Z_test = (
        (scorer.features(causal_windows((test.X - scorer.mean_) / scorer.std_, np.arange(len(test.X)), window)) - mu)
        / sd
    ) @ P
    spread = np.empty(len(known))
    for k in range(len(known)):
        D = nearest(T[owner == k], T[owner == k])
        np.fill_diagonal(D, np.inf)
        spread[k] = np.median(D.min(1))
    pred = S.argmax(1)
    dist = np.empty(len(test.X))
    for k in range(len(known)):
        rows = pred == k
        if rows.any():
            dist[rows] = nearest(Z_test[rows], T[owner == k]).min(1) / spread[k]
    train_dist = np.empty(len(T))  # leave-one-out: each training window against its own class
    for k in range(len(known)):
        D = nearest(T[owner == k], T[owner == k])
        np.fill_diagonal(D, np.inf)
        train_dist[owner == k] = D.min(1) / spread[k]
    top2 = np.sort(S, 1)[:, -2:]
    S_train = F_train @ scorer.coef_.T + scorer.intercept_
    top2_train = np.sort(S_train, 1)[:, -2:]
    terms = {
        "max_score": (-top2[:, 1], -top2_train[:, 1]),
        "margin": (top2[:, 0] - top2[:, 1], top2_train[:, 0] - top2_train[:, 1]),
        "class_distance": (dist, train_dist),
    }
    terms["combined"] = _combined(terms)
    unknown = test.y == left_out
    is_known = np.isin(test.y, known)
    out = {"left_out": data.class_names[left_out], "unknown_frames": int(unknown.sum())}
    z = scorer.novelty_.novelty(scorer.window_features(test.X))
    out["feature_novelty"] = {
        "auc": float(roc_auc_score(unknown[unknown | is_known], z[unknown | is_known])),
        **{f"unknown_rejection_z{lim}": float(np.mean(z[unknown] > lim)) for lim in (1, 2)},
        **{f"known_kept_z{lim}": float(np.mean(z[is_known] <= lim)) for lim in (1, 2)},
    }
    for name, (score, train_score) in terms.items():
        thr = np.quantile(train_score, 0.95)
        out[name] = {
            "auc": float(roc_auc_score(unknown[unknown | is_known], score[unknown | is_known])),
            "unknown_rejection": float(np.mean(score[unknown] > thr)),
            "known_kept": float(np.mean(score[is_known] <= thr)),
        }
    return out


def _combined(terms: dict) -> tuple[np.ndarray, np.ndarray]:
    """Per frame the larger of its margin and class-distance ranks in their training distributions."""

    def rank(name: str, which: int) -> np.ndarray:
        ref = np.sort(terms[name][1])
        return np.searchsorted(ref, terms[name][which]) / len(ref)

    return tuple(np.maximum(rank("margin", i), rank("class_distance", i)) for i in (0, 1))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recordings")
    ap.add_argument("--held-out", default=None, help="recording to probe (default: the first)")
    ap.add_argument("--window", type=int, default=16)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    data = load_recordings(args.recordings)
    held = args.held_out or data.names()[0]
    rows = []
    for c in range(len(data.class_names)):
        if np.any(data.get(held).y == c):
            rows.append(probe(data, held, c, args.window))
            print(json.dumps(rows[-1]), file=sys.stderr)
    if args.json:
        print(json.dumps({"held_out": held, "window": args.window, "pca_dims": PCA_DIMS, "rows": rows}, indent=1))
    else:
        for r in rows:
            cells = "  ".join(
                f"{t}: AUC {r[t]['auc']:.2f} rej {r[t]['unknown_rejection']:.2f} kept {r[t]['known_kept']:.2f}"
                for t in ("max_score", "margin", "class_distance", "combined")
            )
            f = r["feature_novelty"]
            cells += (
                f"  feature_novelty: AUC {f['auc']:.2f} rej z>1 {f['unknown_rejection_z1']:.2f} "
                f"z>2 {f['unknown_rejection_z2']:.2f} kept z<=2 {f['known_kept_z2']:.2f}"
            )
            print(f"{r['left_out']:12s} {cells}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
