"""How much could enrolment buy the UKR class models at most, by moving each class's errors?

Per fold of leave-one-recording-out, ``ukr_clm`` is fitted without enrolment with the parameters
that fold selected in an evaluation (its ``--json`` output), and the held-out recording is
projected.  On its frames after the enrolment (``--enroll K``; docs/segmentation.md, "Enrolment")
the frame-wise best fit (the class of the smallest error, the argmax of the evidence the CLM
groups) is scored:

- ``frame-wise``: as fitted;
- ``enrolment offsets``: per-class offsets of the errors chosen to label the enrolment frames
  best (coordinate search over a grid; ties keep the smaller offset);
- ``enrolment ratios``: each class's errors divided by their median on its enrolment frames,
  times its training frames' own typical error;
- ``oracle offsets``: per-class offsets chosen on the scored frames themselves — an upper bound
  for any adaptation that shifts the classes' errors, which no enrolment can reach;
- with ``--weights R,...``: ``refit ×R`` (frame-wise) and ``ukr_clm refit ×R``, the models refitted
  with the enrolment recording R times among the training recordings (its segments weigh R times
  in the thinned training points, where the ``refit`` adaptation weighs them once);
- with ``--residual-offset N``: ``offset`` (frame-wise) and ``ukr_clm offset``, the held-out
  recording's embedded frames shifted by the mean residual of the enrolment frames on their own
  class's manifold (one offset for the session, the same for every delay; re-estimated N times
  from the shifted frames' projections);
- with ``--session``: models fitted on the enrolment segments alone, in the folds where every
  class's can be fitted (a segment shorter than the delay window cannot): their frame-wise winner,
  the training models' on the same frames, and the class of the smaller of the two models'
  errors relative to each model's own typical error.

Reported: accuracy over the scored frames pooled over the folds (every class of the set known)
and ``ukr_clm``'s own labels for reference.

    python benchmarks/enrolment_bound.py ../shared/data/gesture_phases.npz --selected gp.json [--enroll 1] \
        [--weights 5,20] [--residual-offset 3] [--session] [--json]
"""

from __future__ import annotations

import one_core  # noqa: F401  (one thread for BLAS and numba, set before numpy loads)

# isort: split
import argparse
import json
import sys
from pathlib import Path

import numpy as np
from recording_set import open_recordings

from handflow.plugins.manifold import InvalidInputError
from handflow.plugins.segmenter.datasets import enrolment_recording, enrolment_split
from handflow.plugins.segmenter.evaluation import REGISTRY, RecordingsEvaluator
from handflow.plugins.segmenter.models import Projection

OFFSETS = np.round(np.linspace(-3.0, 3.0, 61), 10)  # error offsets searched, in the models' error units
ROUNDS = 3  # coordinate-search passes over the classes


def winners(errors: np.ndarray, classes: np.ndarray) -> np.ndarray:
    """Per frame the class of the smallest error (the frame-wise winner the CLM groups)."""
    return classes[np.argmin(errors, axis=1)]


def best_offsets(errors: np.ndarray, truth: np.ndarray, classes: np.ndarray) -> np.ndarray:
    """Per-class offsets b (coordinate search over :data:`OFFSETS`) maximising the share of
    ``truth`` equal to the class of the smallest ``errors − b``; ties keep the smaller |b|."""
    b = np.zeros(len(classes))
    for _ in range(ROUNDS):
        for j in range(len(classes)):
            trial = np.tile(b, (len(OFFSETS), 1))
            trial[:, j] = OFFSETS
            right = [np.mean(winners(errors - t, classes) == truth) for t in trial]
            b[j] = max(zip(right, -np.abs(OFFSETS), OFFSETS))[2]
    return b


class Tally:
    """Frames labelled right per variant and frames scored, pooled over the folds."""

    def __init__(self) -> None:
        self.right: dict[str, int] = {}
        self.frames = 0

    def add(self, labels: dict[str, np.ndarray], truth: np.ndarray) -> None:
        for name, lab in labels.items():
            self.right[name] = self.right.get(name, 0) + int(np.sum(lab == truth))
        self.frames += len(truth)

    def report(self) -> dict:
        return {
            "scored_frames": self.frames,
            "accuracy": {name: n / self.frames for name, n in self.right.items()} if self.frames else {},
        }


def fold_labels(errors, y, mask, start, classes, own) -> dict[str, np.ndarray]:
    """Each variant's labels of the scored frames (``start`` on) of one fold."""
    enrol_median = np.array([np.median(errors[mask & (y == c), j]) for j, c in enumerate(classes)])
    scored = errors[start:]
    return {
        "frame-wise": winners(scored, classes),
        "enrolment offsets": winners(scored - best_offsets(errors[mask], y[mask], classes), classes),
        "enrolment ratios": winners(scored / enrol_median * own, classes),
        "oracle offsets": winners(scored - best_offsets(scored, y[start:], classes), classes),
    }


def residual_offset_projections(candidates, X, y, mask, classes, rounds: int):
    """The projection of ``X`` after each of ``rounds`` re-estimations of the session offset: the
    mean, over the enrolment frames (``mask``) and the delays, of their embedded frame minus its
    reconstruction on the manifold of the frame's own class."""
    batched = candidates._batched_projector()
    Y = candidates.pipeline.transform_both(X)[0]
    window = int(candidates.delay.window)
    column = {c: j for j, c in enumerate(classes)}
    own = np.array([column[c] for c in y[mask]])
    offset = np.zeros(Y.shape[1])
    for _ in range(rounds):
        enrolled = (Y - offset)[mask]
        residual = enrolled - batched.project(enrolled)[1][np.arange(len(own)), own]
        step = residual.mean(axis=0).reshape(window, -1).mean(axis=0)
        offset = offset + np.tile(step, window)
        lt, e = candidates._batched_project(batched, Y - offset)
        yield Projection(lt, e, candidates.classes)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("recordings", type=Path)
    ap.add_argument("--selected", type=Path, required=True, help="an evaluation's --json output (ukr_clm's folds)")
    ap.add_argument("--enroll", type=int, default=1)
    ap.add_argument("--weights", default="", help="comma-separated R: refit with the enrolment R times")
    ap.add_argument("--residual-offset", type=int, default=0, help="rounds of the session offset (0: off)")
    ap.add_argument("--session", action="store_true", help="also models fitted on the enrolment alone")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    data = open_recordings(args.recordings)
    if data is None:
        return 2
    folds = {
        f["recording"]: f["selected"] for f in json.loads(args.selected.read_text())["methods"]["ukr_clm"]["folds"]
    }
    ev = RecordingsEvaluator(data, normalise=("training", "recording"), derived=("none", "velocities"))
    method = REGISTRY["ukr_clm"]
    pooled, alone_pooled, unfittable = Tally(), Tally(), []
    for held in data.names():
        params = {k: folds[held][k] for k in ("delay", "history", "derived", "normalise")}
        views = ev.fold_views(held)
        fitted, proj, test = ev._final(method, params, views)
        mask, start = enrolment_split(test.y, ev.known, args.enroll)
        truth = test.y[start:]
        classes = np.array(fitted.classes)
        labels = fold_labels(proj.errors, test.y, mask, start, classes, fitted.model.own_errors)
        labels["ukr_clm"] = method.labels(fitted, proj, folds[held]["reject"])[start:]
        train = views[params["normalise"], params["derived"]][0]
        enrolment = enrolment_recording(test, ev.known, args.enroll)[0]
        for r in (int(w) for w in args.weights.split(",") if w):
            weighted = method.fit(ev._segments([enrolment] * r + train), params, 0)
            state = method.prepare(weighted, test.X)
            labels[f"refit ×{r}"] = winners(state.errors[start:], classes)
            labels[f"ukr_clm refit ×{r}"] = method.labels(weighted, state, folds[held]["reject"])[start:]
        offsets = residual_offset_projections(fitted.model, test.X, test.y, mask, classes, args.residual_offset)
        for n, shifted in enumerate(offsets, 1):
            labels[f"offset {n}"] = winners(shifted.errors[start:], classes)
            labels[f"ukr_clm offset {n}"] = method.labels(fitted, shifted, folds[held]["reject"])[start:]
        pooled.add(labels, truth)
        print(f"{held}: {len(truth)} scored frames", file=sys.stderr)
        if args.session:
            try:
                alone = method.fit(ev._segments([enrolment]), params, 0)
            except InvalidInputError as exc:
                unfittable.append(held)
                print(f"{held}: no models on the enrolment alone ({exc})", file=sys.stderr)
                continue
            errors = method.prepare(alone, test.X).errors[start:]
            own = proj.errors[start:]
            relative = np.minimum(own / fitted.model.own_errors, errors / alone.model.own_errors)
            variants = {"session models": errors, "training models": own, "smaller relative": relative}
            alone_pooled.add({name: winners(e, classes) for name, e in variants.items()}, truth)
    result = pooled.report()
    if args.session:
        result["session_models"] = {"unfittable": unfittable, **alone_pooled.report()}
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        for name, value in result["accuracy"].items():
            print(f"{name:18s} {value:.3f}")
        for name, value in result.get("session_models", {}).get("accuracy", {}).items():
            print(f"{name:18s} {value:.3f} (folds with session models)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
