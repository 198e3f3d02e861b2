"""``handflow evaluate segmentation`` on continuous recordings, ``basicmotions-continuous`` and
``fit-scorer`` (docs/segmentation.md)."""

from __future__ import annotations

import inspect
import json
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

from handflow.framework.files.inputs import missing_modules

from .._moved import renamed
from ..datasets import basicmotions_continuous, load_recordings, segments
from ..evaluation import (
    DEFAULT_METHODS,
    NORMALISATIONS,
    REGISTRY,
    ChosenParameters,
    RecordingsEvaluator,
    calibrate_background,
    calibrate_null_score,
    choice_summary,
    default_jobs,
    methods_to_run,
)
from ..features import DERIVED
from ..models import fit_recording_models, save_class_models
from ..scorers import SCORERS


def _progress(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def run_recordings_evaluation(args, progress) -> int:
    """Leave-one-recording-out evaluation of a folder of CSV recordings or a continuous .npz."""
    t0 = time.perf_counter()
    if args.cv != "leave-one-recording-out":
        print(f"error: continuous recordings support --cv leave-one-recording-out, got {args.cv!r}", file=sys.stderr)
        return 2
    try:
        methods, skipped = methods_to_run(args.methods, DEFAULT_METHODS, REGISTRY, progress)
        data = load_recordings(args.dataset)
        evaluator = RecordingsEvaluator(
            data,
            known=args.known.split(",") if args.known else None,
            methods=methods,
            quick=args.quick,
            random_state=args.seed,
            progress=progress,
            normalise=_choices(args.normalise, NORMALISATIONS),
            pseudo_unknowns=args.pseudo_unknowns,
            derived=_choices(args.derived, DERIVED),
            calibration=args.calibration,
            lag=args.lag,
            jobs=args.jobs or default_jobs(),
            enroll=args.enroll,
            enrol_adaptations=tuple(a for a in args.enroll_adaptation.split(",") if a),
            checkpoints=args.checkpoints,
            chosen=ChosenParameters.load(args.params) if args.params else None,
            cache=args.cache,
            scheduler=args.scheduler,
            preview=args.preview,
            detail=progress if args.verbose else lambda msg: None,
        )
        result = evaluator.evaluate()
    except (ValueError, ImportError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    result["skipped_methods"] = skipped
    result["runtime_s"] = round(time.perf_counter() - t0, 2)
    if args.plots:
        write_recordings_plots(evaluator, result, Path(args.plots))
        progress(f"plots written to {args.plots}")
    print(json.dumps(result, indent=1) if args.json else format_stream_table(result))
    return 0


def _choices(option: str | None, every: tuple[str, ...]) -> tuple[str, ...]:
    """The comma-separated values of ``--normalise`` / ``--derived``; unset: ``every`` (chosen on the inner folds)."""
    return tuple(v for v in option.split(",") if v) if option else every


def protocol_line(result: dict) -> str:
    """What the figures are: the protocol and, for the preview, why they can be optimistic."""
    protocol = result.get("protocol")
    if not protocol:
        return ""
    if protocol["optimistic"]:
        return f"protocol: preview, optimistic — {protocol['reason']}\n"
    return f"protocol: nested — {protocol['reason']}\n"


def format_stream_table(result: dict) -> str:
    cols = ("known_accuracy", "unknown_rejection", "open_set_accuracy", "macro_f1", "segment_f1", "tradeoff_auc")
    lines = [protocol_line(result) + f"{'method':15s} " + " ".join(f"{c:>18s}" for c in cols)]
    for name, r in result["methods"].items():
        cells = ["—".rjust(18) if r.get(c) is None else f"{r[c]:18.3f}" for c in cols]
        lines.append(f"{name:15s} " + " ".join(cells))
        if "agreement" in r:
            lines.append(f"{'':15s} online/batch agreement {r['agreement']:.3f}")
        at = {k: "—" if v is None else f"{v:.3f}" for k, v in r["open_set_accuracy_at_lag"].items()}
        lines.append(
            f"{'':15s} open-set accuracy at lag 0 {at['0']}, at half the window "
            f"({'/'.join(str(f['half_window']) for f in r['folds'])} frames per fold) {at['half_window']}"
        )
        if "enrolment" in r:
            lines.append(f"{'':15s} after the enrolment: {_enrolment_line(r['enrolment'])}")
        if r.get("calibration_note"):
            lines.append(f"{'':15s} note: {r['calibration_note']}")
    return "\n".join(lines)


def _enrolment_line(report: dict) -> str:
    def fig(x: float | None) -> str:
        return "—" if x is None else f"{x:.3f}"

    def named(name: str, a: dict) -> str:
        if "chosen" not in a:
            return name
        counts = Counter(a["chosen"].values())
        return f"{name}: " + ", ".join(f"{choice} in {n}" for choice, n in counts.most_common())

    adapted = ", ".join(
        f"{fig(a['open_set_accuracy'])} with it ({named(name, a)}; gain {fig(a['gain'])})"
        for name, a in report["adaptations"].items()
    )
    return f"open-set accuracy {adapted}, {fig(report['open_set_accuracy_without_enrolment'])} without"


def write_recordings_plots(ev: RecordingsEvaluator, result: dict, folder: Path) -> None:
    from ..plots import plot_confusion, plot_label_ribbons, plot_tradeoff

    names = ev.data.class_names
    for fold in ev.folds_:
        plot_label_ribbons(fold.truth, fold.labels, names, folder / f"ribbons_{fold.recording}.png", fold.recording)
    truth = np.concatenate([f.truth for f in ev.folds_])
    for method in result["methods"]:
        pred = np.concatenate([f.labels[method] for f in ev.folds_])
        plot_confusion(truth, pred, names, folder / f"confusion_{method}.png", method)
    curves = {m: r["tradeoff"] for m, r in result["methods"].items() if r.get("tradeoff")}
    if curves:
        plot_tradeoff(curves, folder / "tradeoff.png", "rejection trade-off (pooled over folds)")


def register_make_continuous(parser) -> None:
    """Write BasicMotions as continuous labelled recordings (cases shuffled and concatenated)."""
    parser.description = (
        "Write BasicMotions as continuous recordings: all train + test cases shuffled with --seed and "
        "concatenated into --recordings recordings (docs/segmentation.md)."
    )
    parser.add_argument("source", help="UEA-style BasicMotions .npz (X_train, labels_train, X_test, labels_test)")
    parser.add_argument("--out", required=True, help="continuous .npz to write")
    parser.add_argument("--recordings", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cases", type=int, help="draw this many cases with replacement (seeded) instead of all once")
    parser.set_defaults(func=run_make_continuous)


def run_make_continuous(args) -> int:
    try:
        arrays = basicmotions_continuous(args.source, args.recordings, args.seed, args.cases)
    except (OSError, KeyError, ValueError) as exc:
        print(f"error: {args.source}: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez(out, **arrays)
    print(f"wrote {args.recordings} recordings to {out}")
    return 0


def register_fit_scorer(parser) -> None:
    """Fit a frame scorer (MiniRocket or DTW 1-NN) for the online CLM on continuous recordings."""
    parser.description = (
        "Fit a frame scorer (MiniRocket or DTW 1-NN over the causal window) on every labelled segment of "
        "continuous recordings, calibrate its null class's score (the rejection threshold) on inner folds of "
        "them and save it without pickle, for the segmenter.online_clm node (docs/segmentation.md)."
    )
    parser.add_argument("recordings", help="folder of labelled CSV recordings or a continuous .npz")
    parser.add_argument("--source", choices=sorted(SCORERS), default="minirocket")
    parser.add_argument("--out", required=True, help="scorer file to write (.npz)")
    parser.add_argument("--window", type=int, default=32, help="frames of the causal window (MiniRocket: >= 9)")
    parser.add_argument("--known", help="comma-separated classes to model (default: all)")
    parser.add_argument("--seed", type=int, default=0, help="MiniRocket's random state")
    parser.set_defaults(func=run_fit_scorer)


def known_segments(path: str, known: str | None, option: str = "--known") -> dict[str, list[np.ndarray]]:
    """Class name → labelled segments of the classes ``known`` (comma-separated; None = all but the data's
    ``unknown_classes``) of
    continuous recordings, or a ValueError that says what to change (naming the ``option``)."""
    data = load_recordings(path)
    names = known.split(",") if known else data.known_classes
    missing = sorted(set(names) - set(data.class_names))
    if missing:
        raise ValueError(f"{option} names classes {missing} that the data lacks; it has {data.class_names}")
    segs = segments(data.recordings, [data.class_names.index(n) for n in names])
    empty = [n for n in names if not segs[data.class_names.index(n)]]
    if empty:
        raise ValueError(f"classes {empty} have no labelled segment of 2+ frames")
    return {n: segs[data.class_names.index(n)] for n in names}


def run_train_recording_models(args, progress) -> int:
    """``train-classes`` on continuous recordings: :func:`..models.fit_recording_models` on every
    labelled segment (``--classes`` = the classes to model), channels z-scored with the models, and
    the background level for the online node calibrated on inner folds
    (:func:`..evaluation.calibrate_background`), reported and stored with the models."""
    t0 = time.perf_counter()
    if args.steps is None:  # the evaluation's class models (docs/segmentation.md)
        args.steps = REGISTRY["ukr_clm"].steps
    try:
        chosen = _chosen_ukr_clm(args.params) if args.params else None
        if chosen is not None:
            args.delay, args.history, args.derived = int(chosen["delay"]), int(chosen["history"]), chosen["derived"]
            progress(f"--params {args.params}: ukr_clm's choice of most folds, {choice_summary(chosen)}")
            if chosen["normalise"] != "training":
                progress(
                    f"warning: the evaluation chose normalisation {chosen['normalise']!r}; train-classes z-scores with "
                    "all training frames (docs/segmentation.md, per-recording normalisation: not built), so the "
                    "models differ from the evaluated ones"
                )
        by_class = known_segments(args.dataset, args.classes, "--classes")
        if args.delay < 1:
            raise ValueError(f"--delay must be >= 1 frame, got {args.delay}")
        if args.history < 1:
            raise ValueError(f"--history must be >= 1 observation, got {args.history}")
        cands = fit_recording_models(
            by_class,
            delay=args.delay,
            n_steps=args.steps,
            random_state=args.seed,
            scaling="standard",
            progress=progress,
            derived=args.derived,
            jobs=getattr(args, "jobs", None) or default_jobs(),
        )
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    background = _chosen_background(args, chosen) if chosen else _calibrated_background(args, list(by_class), progress)
    provenance = {"dataset": str(args.dataset), "steps": args.steps, "history": args.history, **background}
    out = save_class_models(cands, args.out, provenance=provenance)
    progress(
        f"wrote {len(cands)} models (delay {args.delay}, derived {args.derived}; the online node's history "
        f"{args.history}) to {out} in {time.perf_counter() - t0:.1f}s"
    )
    if args.params and (estimate := estimate_line(args.params)) is not None:
        print(estimate)
    return 0


def estimate_line(path: str, method: str = "ukr_clm") -> str | None:
    """How well models trained with the choices of the evaluation result at ``path`` are expected to work
    on new recordings: its leave-one-recording-out figures for ``method``; marked optimistic when the
    settings were chosen on all the recordings (a preview) rather than on each fold's inner folds; None
    when the result holds no figures for it."""
    result = json.loads(Path(path).read_text())
    m = result["methods"][method]
    if "open_set_accuracy" not in m or "known_accuracy" not in m:
        return None
    unknown = m.get("unknown_rejection")
    optimistic = bool(result.get("protocol", {}).get("optimistic"))
    return (
        f"estimate on new recordings (leave one recording out, {len(m['folds'])} folds, {method}): "
        f"open-set accuracy {m['open_set_accuracy']:.3f}, known gestures right {m['known_accuracy']:.3f}"
        + (f", unknown frames rejected {unknown:.3f}" if unknown is not None else "")
        + (
            " — optimistic: the settings were chosen on these same recordings"
            if optimistic
            else " (settings chosen within each fold, on the other recordings)"
        )
    )


def _calibrated_background(args, classes: list[str], progress) -> dict:
    """The background level of the models, chosen on inner folds of the recordings by the
    evaluation's rule, as model provenance (``background_factor``, the online node's default,
    and ``background_calibration``); ``{}`` with a message when the recordings cannot be
    calibrated at all (too few recordings or classes: the node keeps its own default)."""
    try:
        choice = calibrate_background(
            load_recordings(args.dataset), args.delay, args.history, args.derived, classes, args.seed, args.steps
        )
    except ValueError as exc:
        progress(f"background level not calibrated ({exc}); the online node uses its background_factor parameter")
        return {}
    report = {"history": args.history, **_calibration_report(choice)}
    if choice.fallback:
        progress(
            f"background level: rejection cannot be calibrated on this data (best inner-fold objective "
            f"{choice.objective:.3f}, rejecting everything scores 0.5): background_factor 0, rejection off"
        )
    else:
        progress(
            f"background level: background_factor {choice.reject:g} at history {args.history} "
            f"(inner-fold objective {choice.objective:.3f}); the online node uses both by default"
        )
    return {"background_factor": float(choice.reject), "background_calibration": report}


def _chosen_ukr_clm(path: str) -> dict:
    """``ukr_clm``'s choice of most folds in the evaluation result at ``path`` (``--params``)."""
    params = ChosenParameters.load(path)
    params.check(("ukr_clm",), NORMALISATIONS, DERIVED)
    return params.most_frequent("ukr_clm")


def _chosen_background(args, selected: dict) -> dict:
    """The background level an evaluation chose (``--params``), as model provenance: rejection off
    (``background_factor`` 0) where its calibration fell back."""
    off = selected["rejection"] == "off"
    report = {
        "history": args.history,
        "validation_objective": round(float(selected["validation_objective"]), 4),
        "rejection": selected["rejection"],
        "params_from": str(args.params),
    }
    return {"background_factor": 0.0 if off else float(selected["reject"]), "background_calibration": report}


def _calibration_report(choice) -> dict:
    """What a calibrated :class:`..evaluation.Choice` stores with the models or scorer it is for."""
    return {"validation_objective": round(choice.objective, 4), "rejection": "off" if choice.fallback else "calibrated"}


def run_fit_scorer(args) -> int:
    """``fit-scorer``: the scorer fitted on every labelled segment, its null class's score
    calibrated on inner folds of the recordings (:func:`_calibrated_null_score`), saved."""
    t0 = time.perf_counter()
    try:
        cls = SCORERS[args.source]
        if missing := missing_modules(cls.requires):
            raise ImportError(f"--source {args.source} {'; '.join(missing)} (or choose another --source)")
        segs = known_segments(args.recordings, args.known)
        names = list(segs)
        seeded = "random_state" in inspect.signature(cls).parameters
        scorer = cls(window=args.window, **({"random_state": args.seed} if seeded else {}))
        scorer.fit(segs)
    except (ValueError, ImportError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    scorer.null_score_, scorer.null_calibration_ = _calibrated_null_score(args, names)
    out = scorer.save(args.out)
    print(
        f"wrote {args.source} scorer ({len(names)} classes: {', '.join(names)}; window {args.window}) "
        f"to {out} in {time.perf_counter() - t0:.1f}s"
    )
    return 0


def _calibrated_null_score(args, classes: list[str]) -> tuple[float | None, dict | None]:
    """The null class's score of the scorer, chosen on inner folds of the recordings as the
    evaluation's ``clm_<source>`` chooses it (:func:`..evaluation.calibrate_null_score`), and its
    report; ``(None, None)`` with a message when the recordings cannot be calibrated at all (too
    few recordings or classes: the node rejects with its background factor)."""
    try:
        choice = calibrate_null_score(
            load_recordings(args.recordings), args.source, args.window, classes, args.seed, progress=_progress
        )
    except ValueError as exc:
        _progress(f"null class not calibrated ({exc}); the online node rejects with its background_factor")
        return None, None
    report = _calibration_report(choice)
    if choice.fallback:
        _progress(
            f"null class: rejection cannot be calibrated on this data (best inner-fold objective "
            f"{choice.objective:.3f}, rejecting everything scores 0.5): null score -inf, rejection off"
        )
    else:
        _progress(
            f"null class: score {choice.reject:g} on the scorer's scale (inner-fold objective "
            f"{choice.objective:.3f}); the online node uses it by default"
        )
    return float(choice.reject), report


__getattr__ = renamed(
    __name__, {"run_stream_evaluation": "run_recordings_evaluation", "write_stream_plots": "write_recordings_plots"}
)  # the names before the recordings rename
