"""The batched UKR projection of one recording (docs/segmentation.md, "batched projection") with its
kernel in three arrays updated in place, against the kernel as one expression per operation
(``evaluation_fold.py --baseline allocating-kernel``), alternately ``--repeats`` times in this run
on one core; prints the medians, their ratio and whether latents and reconstructions are bitwise
equal (exit code 1 otherwise).  The class models are fitted on the other recordings' segments.

    python benchmarks/projection_kernel.py bm.npz [--held-out rec0] [--repeats 7] [--json]
"""

from __future__ import annotations

import one_core  # noqa: F401  (one thread for BLAS and numba, set before numpy loads)

# isort: split
import argparse
import json
import time
from contextlib import nullcontext
from pathlib import Path

import numpy as np
from evaluation_fold import allocating_kernel
from recording_set import open_recordings

from handflow.plugins.segmenter.datasets import segments
from handflow.plugins.segmenter.models import fit_recording_models


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("recordings", type=Path)
    ap.add_argument("--held-out", default=None, help="recording projected (default: the first)")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    data = open_recordings(args.recordings)
    if data is None:
        return 2
    held = args.held_out or data.names()[0]
    train = [r for r in data.recordings if r.name != held]
    by_class = {str(c): s for c, s in segments(train, range(len(data.class_names))).items() if s}
    cands = fit_recording_models(by_class, delay=8, n_steps=20)
    Y, _ = cands.pipeline.transform_both(next(r.X for r in data.recordings if r.name == held))
    projector = cands._batched_projector()
    seconds: dict[str, list[float]] = {"in_place": [], "allocating": []}
    out = {}
    for _ in range(args.repeats):
        for name in seconds:  # alternately, so both see the same load
            with allocating_kernel() if name == "allocating" else nullcontext():
                start = time.perf_counter()
                out[name] = projector.project(Y)
                seconds[name].append(time.perf_counter() - start)
    now, before = (float(np.median(seconds[k])) for k in ("in_place", "allocating"))
    same = all(np.array_equal(a, b) for a, b in zip(out["in_place"], out["allocating"]))
    result = {
        "frames": len(Y),
        "candidates": len(cands),
        "training_points": [int(n) for n in projector.mask.sum(axis=1)],
        "seconds": now,
        "baseline_seconds": before,
        "ratio": before / now,
        "bitwise_equal": same,
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(
            f"{len(Y)} frames onto {len(cands)} manifolds: in place {now:.2f} s, allocating {before:.2f} s "
            f"(median of {args.repeats}); {result['ratio']:.2f}×; bitwise equal: {same}"
        )
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
