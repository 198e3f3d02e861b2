"""Fitting a MiniRocket scorer (``handflow fit-scorer``, and every MiniRocket fit of ``handflow
evaluate segmentation``): where the time goes, and the feature novelty's subspace by a truncated
SVD against the full SVD it replaced (the baseline, measured in the same run on the same features).

Continuous recordings (e.g. ``../shared/data/gesture_phases.npz``, or BasicMotions made
continuous).  The scorer is fitted on the labelled segments of every recording but the first
(one fold's training set) with window ``--window``; the fit is timed in its parts — MiniRocket
features, the ridge, the feature novelty — then the novelty is fitted again on the same training
features with the full SVD, and the two are compared on the held-out recording's windows (largest
difference of the z-scores).  BLAS and numba are limited to one thread.

    python benchmarks/scorer_fit.py ../shared/data/gesture_phases.npz [--window 32] [--repeats 3] [--json]
"""

from __future__ import annotations

import one_core  # noqa: F401  (one thread for BLAS and numba, set before numpy loads)

# isort: split
import argparse
import json
import time
from pathlib import Path
from unittest import mock

import numpy as np
from recording_set import open_recordings

from handflow.plugins.segmenter.datasets import segments
from handflow.plugins.segmenter.novelty import FeatureNovelty
from handflow.plugins.segmenter.novelty import _feature_novelty as feature_novelty
from handflow.plugins.segmenter.scorers import MiniRocketScorer


def full_svd_directions(Z: np.ndarray, q: int) -> np.ndarray:
    """The baseline: the leading right singular vectors from the full thin SVD."""
    return np.linalg.svd(Z, full_matrices=False)[2][:q]


def timed_fit(train: dict, window: int) -> tuple[MiniRocketScorer, dict, np.ndarray, np.ndarray]:
    """Fit a scorer, timing its parts; also returns the training features and their segment ids."""
    parts = {"features": 0.0, "novelty": 0.0}
    seen: dict = {}
    features, novelty_fit = MiniRocketScorer.features, FeatureNovelty.fit.__func__

    def timed_features(self, windows):
        t = time.perf_counter()
        out = features(self, windows)
        parts["features"] += time.perf_counter() - t
        return out

    def timed_novelty(cls, F, origins):
        seen["F"], seen["origins"] = F, origins
        t = time.perf_counter()
        out = novelty_fit(cls, F, origins)
        parts["novelty"] += time.perf_counter() - t
        return out

    with (
        mock.patch.object(MiniRocketScorer, "features", timed_features),
        mock.patch.object(FeatureNovelty, "fit", classmethod(timed_novelty)),
    ):
        t0 = time.perf_counter()
        scorer = MiniRocketScorer(window=window, random_state=0).fit(train)
        total = time.perf_counter() - t0
    parts = {"total_s": total, "features_s": parts["features"], "novelty_s": parts["novelty"]}
    parts["ridge_and_rest_s"] = total - parts["features_s"] - parts["novelty_s"]
    return scorer, parts, seen["F"], seen["origins"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("recordings", type=Path)
    ap.add_argument("--window", type=int, default=32)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    data = open_recordings(args.recordings)
    if data is None:
        return 2
    recs = data.recordings
    train = recs[1:]
    classes = sorted({int(c) for r in train for c in np.unique(r.y) if c >= 0})
    segs = segments(train, classes)
    fits = [timed_fit({c: segs[c] for c in classes}, args.window) for _ in range(args.repeats)]
    scorer, _, F, origins = fits[-1]
    truncated_s, full_s = [], []
    for _ in range(args.repeats):
        t = time.perf_counter()
        truncated = FeatureNovelty.fit(F, origins)
        truncated_s.append(time.perf_counter() - t)
        with mock.patch.object(feature_novelty, "_leading_directions", full_svd_directions):
            t = time.perf_counter()
            full = FeatureNovelty.fit(F, origins)
            full_s.append(time.perf_counter() - t)
    held_out = scorer.window_features(recs[0].X)
    result = {
        "recordings": str(args.recordings),
        "training_windows": int(len(F)),
        "features": int(F.shape[1]),
        "fit_median": {k: float(np.median([f[1][k] for f in fits])) for k in fits[0][1]},
        "novelty_fit_s": {"truncated_svd": float(np.median(truncated_s)), "full_svd": float(np.median(full_s))},
        "speedup": float(np.median(full_s) / np.median(truncated_s)),
        "max_z_difference": float(np.abs(truncated.novelty(held_out) - full.novelty(held_out)).max()),
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        m, n = result["fit_median"], result["novelty_fit_s"]
        print(f"{result['training_windows']} training windows × {result['features']} features")
        print(
            f"fit {m['total_s']:.1f} s: features {m['features_s']:.1f}, novelty {m['novelty_s']:.1f}, "
            f"ridge and the rest {m['ridge_and_rest_s']:.1f}"
        )
        print(
            f"novelty fit: truncated SVD {n['truncated_svd']:.1f} s vs full SVD {n['full_svd']:.1f} s "
            f"({result['speedup']:.1f}×); z-scores differ by at most {result['max_z_difference']:.1e}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
