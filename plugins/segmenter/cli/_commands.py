"""Commands ``handflow train-classes`` and ``handflow evaluate segmentation`` (docs/segmentation.md)."""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from functools import partial
from pathlib import Path

from ..datasets import DatasetError, is_continuous, load_dataset
from ..evaluation import (
    CALIBRATIONS,
    EXPERIMENTS,
    METHODS,
    NORMALISATIONS,
    PSEUDO_UNKNOWNS,
    REGISTRY,
    SELECTIONS,
    Evaluator,
    TrajectoryProtocol,
    UKROnlyMethod,
    default_jobs,
    heading_choices,
    methods_to_run,
)
from ..features import DERIVED, RunningStandardizer
from ..models import (
    INITS,
    KERNELS,
    ModelsMissingError,
    candidate_set,
    load_candidates,
    save_class_models,
    train_class_models,
)
from ._recordings import _progress, protocol_line, run_recordings_evaluation, run_train_recording_models

TRAJECTORY_STEPS = 300  # RPROP steps per class model on labelled trajectories (the thesis' models)


def _add_dataset_args(parser: argparse.ArgumentParser, steps_help: str = "UKR optimisation steps per class") -> None:
    parser.add_argument(
        "dataset",
        help="folder with train/validation/test sub-folders of <label>_*.csv, or an .npz (see docs/segmentation.md)",
    )
    parser.add_argument("--classes", help="comma-separated subset of class labels to use")
    parser.add_argument(
        "--keep-pen-lift",
        action="store_true",
        help="keep the pen-lift tail marked in an .npz's metadata (default: cut it)",
    )
    parser.add_argument("--beta", default="auto", help="periodic UKR bandwidth, or 'auto' = 12·mean_length/45")
    parser.add_argument("--steps", type=int, default=TRAJECTORY_STEPS, help=steps_help)
    parser.add_argument(
        "--init",
        choices=INITS,
        default="equidistant",
        help="latent init of the class manifolds (equidistant over the period, or isomap)",
    )
    parser.add_argument(
        "--kernel",
        choices=KERNELS,
        default="periodic",
        help="time kernel of the class manifolds; periodic_quartic trains on every point in linear time",
    )
    parser.add_argument(
        "--headings",
        help="comma-separated channels (names or 0-based indices, e.g. 0,1 for a pen's x,y) whose direction "
        "of motion is appended to every observation, or 'none'; default: none for train-classes, chosen by "
        "evaluate segmentation's validation split between none and 0,1 (docs/segmentation.md, heading channels)",
    )
    parser.add_argument("--seed", type=int, default=0)


def heading_channels(spec: str | None, columns: list[str]) -> tuple[int, ...]:
    """Column indices of a ``--headings`` value (names or 0-based indices; ``none`` or unset: none)."""
    if spec is None or spec.strip() == "none":
        return ()
    out = []
    for item in filter(None, (part.strip() for part in spec.split(","))):
        if item in columns:
            out.append(columns.index(item))
        elif item.isdigit() and int(item) < len(columns):
            out.append(int(item))
        else:
            raise DatasetError(
                f"--headings: no channel {item!r}; the data's channels are {columns} (or 0–{len(columns) - 1})"
            )
    return tuple(out)


def _dataset(args):
    ds = load_dataset(args.dataset, trim_pen_lift=not args.keep_pen_lift)
    return ds.restrict(args.classes.split(",")) if args.classes else ds


def _beta(args):
    if args.beta == "auto":
        return "auto"
    try:
        return float(args.beta)
    except ValueError:
        raise DatasetError(f"--beta must be a number or 'auto', got {args.beta!r}") from None


# -- train-classes ------------------------------------------------------------------------------
def register_train_classes(parser: argparse.ArgumentParser) -> None:
    """Train one structured UKR manifold (periodic time) per class of a labelled dataset or of recordings."""
    parser.description = (
        "Train one structured UKR manifold (1D periodic time) per class: of a labelled dataset's train split "
        "(the thesis' models), or of every labelled segment of continuous recordings (delay-embedded models "
        "for real streams, docs/segmentation.md)."
    )
    _add_dataset_args(
        parser,
        steps_help=f"UKR optimisation steps per class (default: {TRAJECTORY_STEPS} on labelled trajectories; on continuous "
        "recordings 150, the steps of the class models `evaluate segmentation` scores)",
    )
    parser.set_defaults(steps=None)
    parser.add_argument("--out", required=True, help="output folder (gets <label>.npz and classes.json)")
    parser.add_argument(
        "--jobs",
        type=int,
        help="continuous recordings: the class models are fitted over this many processes, one BLAS thread each "
        "(default: the cores; 1 = one after the other; the same models either way)",
    )
    parser.add_argument(
        "--delay",
        type=int,
        default=8,
        help="continuous recordings: frames of the delay embedding of the class models (docs/segmentation.md)",
    )
    parser.add_argument(
        "--derived",
        choices=DERIVED,
        default="none",
        help="continuous recordings: 'velocities' appends each channel's step from the frame before; the models "
        "derive it from raw streams themselves (choose it with `evaluate segmentation --derived none,velocities`)",
    )
    parser.add_argument(
        "--history",
        type=int,
        default=10,
        help="continuous recordings: the CLM neighbourhood H at which the background level is calibrated on inner "
        "folds for the online node, stored with the models: the node's history unless its parameter is set "
        "(default 10; docs/segmentation.md)",
    )
    parser.add_argument(
        "--params",
        metavar="RESULT.json",
        help="continuous recordings: train what an `evaluate segmentation --json` result chose for ukr_clm in most "
        "folds (ties to the first fold) — its delay, history, derived features and background level — instead of "
        "--delay, --history, --derived and the calibration (docs/segmentation.md)",
    )
    parser.set_defaults(func=run_train_classes)


def _train(ds, args, headings: tuple[int, ...]):
    """One manifold per class of ``ds`` with the command's training options and those heading channels."""
    return train_class_models(
        ds,
        beta=_beta(args),
        n_steps=args.steps,
        init=args.init,
        random_state=args.seed,
        progress=_progress,
        kernel=args.kernel,
        headings=headings,
    )


def _train_each(ds, args, choices: tuple[tuple[int, ...], ...]) -> list:
    """One candidate set per heading channels of ``choices``, the sets trained side by side over
    ``--jobs`` forked processes (the same models as one after the other)."""
    jobs = min(args.jobs or default_jobs(), len(choices))
    if jobs <= 1:
        return [candidate_set(_train(ds, args, headings)) for headings in choices]
    with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("fork")) as pool:
        return [candidate_set(models) for models in pool.map(partial(_train, ds, args), choices)]


def _fold_trainer(args):
    """The training of the heading choice's cross-fitted splits (docs/segmentation.md): the
    command's training options on a fold's train split, without the per-class progress lines."""

    def train(ds, headings: tuple[int, ...]):
        return candidate_set(
            train_class_models(
                ds,
                beta=_beta(args),
                n_steps=args.steps,
                init=args.init,
                random_state=args.seed,
                kernel=args.kernel,
                headings=headings,
            )
        )

    return train


HEADINGS_ON_RECORDINGS = "error: --headings applies to labelled trajectories, not to continuous recordings (drop it)"


def run_train_classes(args) -> int:
    if is_continuous(args.dataset):
        if args.headings:
            print(HEADINGS_ON_RECORDINGS, file=sys.stderr)
            return 2
        return run_train_recording_models(args, _progress)
    if args.steps is None:
        args.steps = TRAJECTORY_STEPS
    try:
        if args.derived != "none":
            raise DatasetError("--derived applies to continuous recordings (docs/segmentation.md)")
        ds = _dataset(args)
        models = _train(ds, args, heading_channels(args.headings, ds.columns))
    except (DatasetError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    out = save_class_models(
        models,
        args.out,
        provenance={
            "dataset": ds.source,
            "split": "train",
            "steps": args.steps,
            "beta": str(args.beta),
            "init": args.init,
            "headings": args.headings or "",
        },
    )
    _progress(f"wrote {len(models)} models to {out}")
    return 0


# -- evaluate segmentation ----------------------------------------------------------------------
def register_evaluate(parser: argparse.ArgumentParser) -> None:
    """Run the recognition/segmentation protocol for the UKR methods and the baselines; print a table."""
    parser.description = (
        "Run the thesis recognition/segmentation protocol (docs/segmentation.md §D) for "
        "ukr_only, ukr_clm and the dtw_1nn / hmm baselines: validation picks parameters, "
        "test reports."
    )
    _add_dataset_args(parser)
    parser.add_argument("--models", help="folder written by train-classes (default: train on the train split)")
    parser.add_argument("--json", action="store_true", help="print the full result as JSON on stdout")
    parser.add_argument("--plots", help="folder for figures (labelled trajectories, compatibilities, summary)")
    parser.add_argument("--quick", action="store_true", help="reduced protocol (N^th 1,2; H 10; 2 CLM runs; 6 pairs)")
    parser.add_argument(
        "--jobs",
        type=int,
        help="continuous recordings: folds run over this many processes, one BLAS thread each (default: the "
        "cores; 1 = one after the other, the same figures either way; docs/segmentation.md); labelled "
        "trajectories: the selection's runs, folds and the test cases, likewise",
    )
    parser.add_argument(
        "--scheduler",
        metavar="tcp://HOST:PORT",
        help="continuous recordings: run the folds on the dask.distributed cluster of this scheduler instead of "
        "local processes, with the same figures (pip install 'handflow[cluster]' here and on every worker; "
        "docs/segmentation.md)",
    )
    parser.add_argument(
        "--cache",
        metavar="DIR",
        help="continuous recordings: keep every method's part of every fold in DIR and take it from there when a "
        "later run has the same recordings, settings and code — a run that adds a method or only changes the "
        "report computes just what is new; DIR can be deleted at any time (docs/segmentation.md)",
    )
    parser.add_argument(
        "--params",
        metavar="RESULT.json",
        help="continuous recordings: rerun the parameters an earlier --json result chose, without selection — per "
        "fold for the recordings it held out (the same labels), its most frequent choice for others "
        "(docs/segmentation.md)",
    )
    parser.add_argument(
        "--preview",
        action="store_true",
        help="explore in minutes: every candidate is scored once on the reported folds (continuous recordings: the "
        "leave-one-recording-out folds; labelled trajectories: the test cases, fitted on the train split) by the "
        "nested protocol's own objective, one choice per method for all folds — cross-validated grid search, "
        "optimistic like scikit-learn's best_score_; the JSON's 'protocol' says so. Publish the default (nested) "
        "protocol's figure (docs/segmentation.md, Which protocol when)",
    )
    parser.add_argument(
        "--verbose",
        action="store_true",
        help="continuous recordings: also print every candidate's calibration and each fold's full choice "
        "(default: one line per fold and method)",
    )
    parser.add_argument(
        "--checkpoints",
        metavar="DIR",
        help="continuous recordings: keep every finished fold in DIR; a later run with the same recordings and "
        "settings takes the folds from there, so an interrupted evaluation resumes (docs/segmentation.md)",
    )
    parser.add_argument(
        "--methods",
        help=f"subset of {','.join(METHODS)} (continuous recordings: also ukr_clm_online, minirocket, clm_minirocket, "
        "clm_dtw, clm_minirocket_novelty, clm_dtw_novelty; default all but clm_dtw and the *_novelty methods, "
        "less those whose extra is not installed: hmm needs handflow[hmm], the minirocket ones handflow[minirocket]; "
        "a method named here without its extra is an error)",
    )
    parser.add_argument(
        "--cv",
        default="leave-one-recording-out",
        help="continuous recordings: cross-validation scheme (leave-one-recording-out)",
    )
    parser.add_argument(
        "--known", help="continuous recordings: comma-separated classes to model; frames of others must be rejected"
    )
    parser.add_argument(
        "--select",
        choices=[s.replace("_", "-") for s in SELECTIONS],
        help="labelled trajectories: what the validation split selects parameters by — 'open-set' (default): "
        "the mean of the recognition and the rejection experiments' shares, so one operating point keeps "
        "known motions and rejects reversed and left-out ones; 'recognition': the recognition experiments "
        "only, as in the thesis (docs/segmentation.md §D)",
    )
    parser.add_argument(
        "--normalise",
        help="continuous recordings, every method alike: comma-separated normalisations to choose among on the inner "
        f"folds, per method and fold — default all of {','.join(NORMALISATIONS)}; 'training' z-scores every "
        "recording with the fold's training frames; 'recording' standardises each recording causally, frame by "
        f"frame, with its running mean/std and those training statistics as a prior of "
        f"{RunningStandardizer().prior_frames} frames — for recordings of different people or sensor placements "
        "(docs/segmentation.md)",
    )
    parser.add_argument(
        "--pseudo-unknowns",
        choices=PSEUDO_UNKNOWNS,
        default="refit",
        help="continuous recordings: how the calibration makes a known class unknown — 'refit' (default) refits "
        "a classifier trained on all classes at once (MiniRocket's ridge) without it, so its frames are as "
        "unknown as a class never seen; 'drop' only drops its decision column (faster, and optimistic: "
        "rejection then comes out too weak). Per-class models (UKR, DTW, HMM) leave the class's model out "
        "either way (docs/segmentation.md)",
    )
    parser.add_argument(
        "--derived",
        help="continuous recordings, every method alike: comma-separated derived features to choose among on "
        f"the inner folds, per method and fold — default all of {','.join(DERIVED)}: 'none' keeps the channels, "
        "'velocities' appends each channel's step from the frame before, before the scaling (docs/segmentation.md)",
    )
    parser.add_argument(
        "--calibration",
        choices=CALIBRATIONS,
        default=CALIBRATIONS[0],
        help="continuous recordings: 'fallback' (default) switches rejection off for a method and fold when no "
        "operating point beats rejecting everything on the inner folds (the result says so, per fold); 'strict' "
        "takes the operating point of the best validation objective, whatever it is (docs/segmentation.md)",
    )
    parser.add_argument(
        "--lag",
        type=int,
        default=0,
        help="continuous recordings: label each frame from the evidence of the window ending this many frames "
        "later (latency for accuracy); every method is also reported at lag 0 and at half its window "
        "(docs/segmentation.md)",
    )
    parser.add_argument(
        "--enroll",
        type=int,
        default=0,
        help="continuous recordings: every method also gets the first K labelled segments per known class of the "
        "held-out recording (as a user enrols at the start of a session) and is scored with and without them on "
        "the frames after them (default 0 = off; docs/segmentation.md, Enrolment)",
    )
    parser.add_argument(
        "--enroll-adaptation",
        default="chosen",
        help="with --enroll: comma-separated ways to adapt, each reported, the first at the top — 'chosen' "
        "(default): per method and fold, whichever of no enrolment, 'refit' and 'align' labels the inner folds' "
        "frames after their own enrolment best; 'align': every recording is also standardised with the mean and "
        "spread of its own enrolment segments; 'refit': the segments are extra training data only "
        "(docs/segmentation.md, Enrolment)",
    )
    parser.set_defaults(func=run_evaluate)


def run_evaluate(args) -> int:
    if is_continuous(args.dataset):
        if args.headings:
            print(HEADINGS_ON_RECORDINGS, file=sys.stderr)
            return 2
        if args.select:
            print(
                "error: --select applies to labelled trajectories; continuous recordings calibrate by the "
                "open-set objective of docs/segmentation.md (drop --select)",
                file=sys.stderr,
            )
            return 2
        return run_recordings_evaluation(args, _progress)
    t0 = time.perf_counter()
    try:
        if args.enroll:
            raise DatasetError("--enroll applies to continuous recordings (docs/segmentation.md, Enrolment)")
        if args.checkpoints or args.params or args.cache or args.scheduler:
            raise DatasetError(
                "--checkpoints, --cache, --params and --scheduler apply to continuous recordings (docs/segmentation.md)"
            )
        if (args.normalise, args.pseudo_unknowns, args.derived, args.calibration, args.lag) != (
            None,
            "refit",
            None,
            CALIBRATIONS[0],
            0,
        ):
            raise DatasetError(
                "--normalise, --pseudo-unknowns, --derived, --calibration and --lag apply to continuous recordings "
                "(docs/segmentation.md)"
            )
        methods, skipped = methods_to_run(args.methods, METHODS, METHODS, _progress)
        ds = _dataset(args)
        if args.models:
            if args.headings:
                raise DatasetError(
                    f"drop --headings: the models in {args.models} keep the heading channels they were trained with"
                )
            candidates, alternatives, trainer = load_candidates(args.models), (), None
        else:
            choices = (
                heading_choices(len(ds.columns))
                if args.headings is None
                else (heading_channels(args.headings, ds.columns),)
            )
            _progress(f"training one manifold per class ({len(ds.classes)} classes) per heading channels {choices}")
            candidates, *alternatives = _train_each(ds, args, choices)
            trainer = _fold_trainer(args) if len(choices) > 1 and not args.preview else None
        protocol = replace(
            TrajectoryProtocol.quick() if args.quick else TrajectoryProtocol(),
            selection=(args.select or "open-set").replace("-", "_"),
        )
        evaluator = Evaluator(
            ds,
            candidates,
            protocol,
            random_state=args.seed,
            progress=_progress,
            alternatives=tuple(alternatives),
            trainer=trainer,
            jobs=args.jobs or default_jobs(),
            preview=args.preview,
        )
    except (DatasetError, ModelsMissingError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    result = evaluator.evaluate(methods)
    result["skipped_methods"] = skipped
    result["parameters"].update(
        steps=args.steps,
        beta=str(args.beta),
        init=args.init,
        quick=bool(args.quick),
        seed=args.seed,
        headings="validation" if args.headings is None and not args.models else args.headings or "",
    )
    result["runtime_s"] = round(time.perf_counter() - t0, 2)
    if args.plots:
        write_plots(evaluator, result, Path(args.plots))
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        print(format_table(result))
    return 0


def format_table(result: dict) -> str:
    """Plain-text summary: share ≥ 85 % / share perfect / mean correct per method and experiment."""
    lines = [
        protocol_line(result) + f"{'method':10s} " + " ".join(f"{e:>22s}" for e in EXPERIMENTS),
        f"{'':10s} " + " ".join(f"{'>=85% perfect mean':>22s}" for _ in EXPERIMENTS),
    ]
    for m, exps in result["methods"].items():
        cells = []
        for e in EXPERIMENTS:
            r = exps[e]
            cells.append(
                "—".rjust(22)
                if r["mean_correct"] is None
                else f"{r['share_ge_85']:6.2f} {r['share_perfect']:7.2f} {r['mean_correct']:6.2f}".rjust(22)
            )
        lines.append(f"{m:10s} " + " ".join(cells))
    return "\n".join(lines)


def write_plots(ev: Evaluator, result: dict, folder: Path) -> None:
    """Thesis-like figures for the first test case of every experiment (middle H, every point)."""
    from ..clm import UKROnlyRecognizer
    from ..plots import plot_compatibilities, plot_labelled_trajectory, plot_summary

    H = ev.protocol.histories[len(ev.protocol.histories) // 2]
    for exp in EXPERIMENTS:
        case = next((c for c in ev.cases["test"] if c.experiment == exp and c.history == H and c.nth == 1), None)
        if case is None:
            continue
        Y = ev.sequence("test", case)
        for method in (m for m in METHODS if REGISTRY[m].manifolds):
            params = result["parameters"]["selected"].get(method)
            if params is None:
                continue
            labels = ev.chosen[method].predict(method, params, "test", case)
            plot_labelled_trajectory(
                Y,
                labels,
                ev.classes,
                folder / f"{exp}_{method}.png",
                f"{method}: {exp} {case.name} H={H}",
                truth=case.truth,
            )
        if UKROnlyMethod.name in result["parameters"]["selected"]:
            chosen = ev.chosen[UKROnlyMethod.name]
            proj = chosen.projection("test", case)
            rec = UKROnlyRecognizer(
                chosen.case_candidates(case),
                history=H,
                **result["parameters"]["selected"][UKROnlyMethod.name],
            )
            plot_compatibilities(
                rec.compatibilities_projected(proj),
                proj.classes,
                folder / f"{exp}_compatibilities.png",
                f"UKR-only C(t): {exp} {case.name}",
            )
    plot_summary(result, folder / "summary.png")
    _progress(f"plots written to {folder}")
