"""The calibration's objective over a fine sweep of one method's rejection value, on the inner
folds of one held-out recording: is there an operating point that beats rejecting everything?

`handflow evaluate segmentation` chooses each method's rejection value on the inner folds by
mean(known accuracy, pseudo-unknown rejection) (docs/segmentation.md); rejecting everything
scores 0.5.  This prints, for every derived-feature choice and grid point of the method, the
known accuracy, the pseudo-unknown rejection (per left-out class and their mean) and the
objective at each value of a sweep: the method's own sweep, or with ``--fine`` a geometric one
(ratio 2^(1/4)) over the background factor of the CLM methods.  The same evaluator code builds
the folds, models and pseudo-unknowns as the evaluation.

    python benchmarks/calibration_curve.py ../shared/data/gesture_phases.npz --held-out a1 \
        --method ukr_clm --normalise recording --derived none,velocities --fine [--json]
"""

from __future__ import annotations

import one_core  # noqa: F401  (one thread for BLAS and numba, set before numpy loads)

# isort: split
import argparse
import json
import sys

import numpy as np

from handflow.plugins.segmenter.datasets import load_recordings
from handflow.plugins.segmenter.evaluation import REGISTRY, RecordingsEvaluator, ScoreCLMMethod, UKRCLMMethod
from handflow.plugins.segmenter.evaluation._calibration import inner_folds

FINE = 2.0 ** np.arange(-5, 6.01, 0.25)  # background factors 1/32 … 64


def curve(ev: RecordingsEvaluator, method_name: str, held: str, fine: bool) -> list[dict]:
    """One row per (normalisation, derived, params, rejection value) on the inner folds of fold ``held``."""
    method = REGISTRY[method_name]
    rows = []
    for (normalise, derived), (train, _) in ev.fold_views(held).items():
        for params in method.grid(ev.quick):
            params = {**params, "derived": derived, "normalise": normalise}
            known_acc, pseudo_rej, sweep = ev.validation(method, inner_folds(train), params)
            for r in np.r_[0.0, FINE] if fine else sweep:
                known, rejection = known_acc(r), pseudo_rej(r)
                rows.append(
                    {
                        "params": params,
                        "reject": float(r),
                        "known_accuracy": known,
                        "pseudo_rejection": rejection,
                        "objective": 0.5 * (known + rejection),
                    }
                )
                print(
                    f"{normalise:>9} {derived:>10} {params} r={r:9.4g} known={known:.3f} pseudo-rejection={rejection:.3f} "
                    f"objective={rows[-1]['objective']:.4f}",
                    file=sys.stderr,
                    flush=True,
                )
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recordings")
    ap.add_argument("--held-out", default=None, help="outer fold whose inner folds are swept (default: the first)")
    ap.add_argument("--method", default="ukr_clm", choices=sorted(n for n, m in REGISTRY.items() if m.batch is None))
    ap.add_argument("--known", default=None, help="comma-separated classes to model (default all)")
    ap.add_argument(
        "--normalise", default="training", help="comma-separated normalisation choices, as in the evaluation"
    )
    ap.add_argument("--derived", default="none", help="comma-separated derived-feature choices, as in the evaluation")
    ap.add_argument("--fine", action="store_true", help="a geometric background sweep instead of the method's own")
    ap.add_argument("--full", action="store_true", help="the full grid instead of the evaluation's --quick one")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if args.fine and not isinstance(REGISTRY[args.method], (UKRCLMMethod, ScoreCLMMethod)):
        ap.error(f"--fine sweeps a background factor; {args.method} rejects by a score threshold (drop --fine)")
    data = load_recordings(args.recordings)
    held = args.held_out or data.names()[0]
    ev = RecordingsEvaluator(
        data,
        known=args.known.split(",") if args.known else None,
        methods=(args.method,),
        quick=not args.full,
        normalise=tuple(args.normalise.split(",")),
        derived=tuple(args.derived.split(",")),
    )
    rows = curve(ev, args.method, held, args.fine)
    best = max(rows, key=lambda row: row["objective"])
    print(
        f"best objective {best['objective']:.4f} at {best['params']} r={best['reject']:.4g} "
        f"(rejecting everything: 0.5; known accuracy + pseudo-unknown rejection > 1 at "
        f"{sum(row['objective'] > 0.5 for row in rows)} of {len(rows)} points)",
        file=sys.stderr if args.json else sys.stdout,
    )
    if args.json:
        print(json.dumps({"held_out": held, "method": args.method, "rows": rows, "best": best}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
