"""One fold of `handflow evaluate segmentation` on continuous recordings, timed per method, against
the same fold run with the code before a speed-up (the baseline, run in the same process):

- ``--baseline feature-novelty``: every MiniRocket fit also fits its feature novelty (before,
  the methods that do not use it fitted it too);
- ``--baseline einsum``: the batched UKR projection (:mod:`handflow.plugins.segmenter.models`)
  with its kernel-weighted sums and grid distances as plain ``np.einsum`` contractions, not
  matrix products;
- ``--baseline allocating-kernel``: the projection's kernel and its derivative as one numpy
  expression each (a new (B, M, N) array per operation), not three arrays updated in place.

The two runs must select the same parameters, rejection values up to rounding (exit code 1
otherwise); the script prints each method's wall time, the ratio and the share of frames
labelled alike (sums in another order may move a projection by ~1e-12, and the CLM's iterations
can carry that to a frame's label).  BLAS and numba are limited to one thread.

    python benchmarks/evaluation_fold.py ../shared/data/gesture_phases.npz --held-out a1 \
        --methods minirocket,clm_minirocket --baseline feature-novelty [--quick] [--json]
"""

from __future__ import annotations

import one_core  # noqa: F401  (one thread for BLAS and numba, set before numpy loads)

# isort: split
import argparse
import json
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from recording_set import open_recordings

from handflow.plugins.segmenter.evaluation import REGISTRY, MiniRocketMethod, RecordingsEvaluator
from handflow.plugins.segmenter.models import BatchedPeriodicProjector


@contextmanager
def feature_novelty_everywhere():
    """Every MiniRocket scorer of the evaluation fits its feature novelty, as before."""
    scorers = [m for m in REGISTRY.values() if isinstance(m, MiniRocketMethod)]
    scorers += [m.scorer for m in REGISTRY.values() if isinstance(getattr(m, "scorer", None), MiniRocketMethod)]
    before = [m.has_features for m in scorers]
    for m in scorers:
        m.has_features = True
    try:
        yield
    finally:
        for m, had in zip(scorers, before):
            m.has_features = had


@contextmanager
def einsum_projection():
    """The batched projector's contractions as the plain einsums they were."""
    weighted, grid = BatchedPeriodicProjector._weighted, BatchedPeriodicProjector._grid_products
    BatchedPeriodicProjector._weighted = lambda self, w: np.einsum("bmn,mnd->bmd", w, self.Y)
    BatchedPeriodicProjector._grid_products = lambda self, Y: np.einsum("bd,gmd->bgm", Y, self.grid_images)
    try:
        yield
    finally:
        BatchedPeriodicProjector._weighted, BatchedPeriodicProjector._grid_products = weighted, grid


@contextmanager
def allocating_kernel():
    """The batched projector's kernel as the expressions it was (padding masked out of the minimum)."""

    def f(self, x, jacobian=False):
        delta = x[:, :, None] - self.X[None]
        s = np.sin(delta)
        u = self.half_beta2[None, :, None] * s * s
        u -= np.min(np.where(self.mask[None] > 0, u, np.inf), axis=2, keepdims=True)
        k = np.exp(-u) * self.mask[None]
        S = k.sum(axis=2)
        F = self._weighted(k) / S[:, :, None]
        if not jacobian:
            return F, None
        dk = -k * self.half_beta2[None, :, None] * np.sin(2.0 * delta)
        return F, (self._weighted(dk) - F * dk.sum(axis=2)[:, :, None]) / S[:, :, None]

    in_place, BatchedPeriodicProjector._f = BatchedPeriodicProjector._f, f
    try:
        yield
    finally:
        BatchedPeriodicProjector._f = in_place


BASELINES = {
    "feature-novelty": feature_novelty_everywhere,
    "einsum": einsum_projection,
    "allocating-kernel": allocating_kernel,
}


def timed_fold(data, held: str, methods: tuple[str, ...], quick: bool, **views) -> tuple[dict, object]:
    """Seconds per method (from the evaluator's own progress lines) and the fold's result;
    ``views``: the evaluator's ``normalise`` and ``derived`` (default its own, one view)."""
    marks: dict[str, float] = {}
    start = time.perf_counter()

    def progress(msg: str) -> None:
        words = msg.split()
        if len(words) > 1 and words[0] == f"{held}:" and words[1] in methods:
            marks[words[1]] = time.perf_counter()

    ev = RecordingsEvaluator(data, methods=methods, quick=quick, progress=progress, **views)
    fold = ev.run_fold(held)
    seconds, last = {}, start
    for name in methods:
        if name in marks:
            seconds[name], last = marks[name] - last, marks[name]
    return seconds, fold


def _same(a: dict, b: dict) -> bool:
    """Equal selections; rejection values (quantiles of the scores) up to rounding."""
    return a.keys() == b.keys() and all(
        np.isclose(a[k], b[k], rtol=1e-6) if isinstance(a[k], float) else a[k] == b[k] for k in a
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("recordings", type=Path)
    ap.add_argument("--held-out", default=None, help="recording held out (default: the first)")
    ap.add_argument("--methods", default="minirocket,clm_minirocket")
    ap.add_argument("--baseline", choices=sorted(BASELINES), default="feature-novelty")
    ap.add_argument("--quick", action="store_true", help="the evaluation's --quick grids")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    data = open_recordings(args.recordings)
    if data is None:
        return 2
    held = args.held_out or data.names()[0]
    methods = tuple(args.methods.split(","))
    now, fold = timed_fold(data, held, methods, args.quick)
    with BASELINES[args.baseline]():
        before, fold_before = timed_fold(data, held, methods, args.quick)
    agreement = {m: float(np.mean(fold.labels[m] == fold_before.labels[m])) for m in fold.labels}
    same_selection = all(_same(fold.selected[m], fold_before.selected[m]) for m in fold.labels)
    result = {
        "recordings": str(args.recordings),
        "held_out": held,
        "baseline": args.baseline,
        "seconds": now,
        "baseline_seconds": before,
        "total_ratio": sum(before.values()) / sum(now.values()),
        "same_selection": same_selection,
        "label_agreement": agreement,
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for name in now:
            print(f"{name}: {now[name]:.1f} s (baseline {args.baseline}: {before[name]:.1f} s)")
        print(
            f"fold {sum(now.values()):.1f} s vs {sum(before.values()):.1f} s ({result['total_ratio']:.2f}×); "
            f"same selection: {same_selection}; frames labelled as by the baseline: "
            + ", ".join(f"{m} {share:.4f}" for m, share in agreement.items())
        )
    return 0 if same_selection else 1


if __name__ == "__main__":
    raise SystemExit(main())
