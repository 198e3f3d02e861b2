"""The figures of an evaluation from its folds' labels (docs/segmentation.md, "reading the
output"): per method the pooled frame metrics, the labels at lag 0 and at half the method's
window, the rejection trade-off, the folds where rejection was switched off and why."""

from __future__ import annotations

from collections import Counter

import numpy as np

from ..base import lagged
from ._calibration import FALLBACK_MARGIN, REJECT_ALL_OBJECTIVE
from ._chosen import REPORTED
from ._enrolment import enrolment_report
from ._fold_result import FoldResult
from ._methods import REGISTRY
from ._metrics import frame_metrics, segment_f1, tradeoff_curve
from ._third_party import summary


def _degenerate_calibration(
    truth: np.ndarray,
    pred: np.ndarray,
    known: list[int],
    selected: list[dict],
    no_rejection: dict | None,
    where: str = "the inner folds",
) -> str | None:
    """What a user needs to know when the calibration chose to reject (nearly) every known frame
    because, on validation, nothing did better than rejecting everything; ``None`` otherwise."""
    is_known = np.isin(truth, known)
    rejected = float(np.mean(pred[is_known] == -1)) if is_known.any() else 0.0
    best = max(s.get("validation_objective", 1.0) for s in selected)
    if rejected < 0.9 or best > REJECT_ALL_OBJECTIVE + FALLBACK_MARGIN:
        return None
    return (
        f"{rejected:.0%} of the known frames are rejected: on {where} no operating point kept "
        f"known frames and rejected left-out classes better than rejecting everything (best validation "
        f"objective {best:.3f}; rejecting everything scores {REJECT_ALL_OBJECTIVE}). The classes are not "
        "separable enough here for open-set rejection"
        + (
            f"; without rejection {no_rejection['known_accuracy']:.3f} of the known frames are right ('no_rejection')"
            if no_rejection and no_rejection.get("known_accuracy") is not None
            else ""
        )
        + "; the default calibration (fallback) switches rejection off in that case"
    )


def _fallback_note(folds: int, fell_back: int, strict: dict | None, where: str = "the inner folds") -> str | None:
    """What a user needs to know when the calibration switched rejection off in some folds;
    ``None`` when it never did."""
    if not fell_back:
        return None
    return (
        f"rejection is off in {fell_back} of {folds} folds: on {where} no operating point kept known "
        f"frames and rejected left-out classes better than rejecting everything (objective <= "
        f"{REJECT_ALL_OBJECTIVE + FALLBACK_MARGIN:.2f}; rejecting everything scores {REJECT_ALL_OBJECTIVE}), so the "
        "classes are not separable enough here for open-set rejection and every frame keeps its best label"
        + (
            f"; the objective's own choice would label {strict['open_set_accuracy']:.3f} of the frames right ('strict')"
            if strict and strict.get("open_set_accuracy") is not None
            else ""
        )
    )


_NOT_GRID = ("normalise", "derived", *REPORTED)


def choice_summary(selected: dict) -> str:
    """A method's choice in a fold, for the progress line: view, grid point, rejection, objective."""
    grid = ", ".join(f"{k} {v}" for k, v in selected.items() if k not in _NOT_GRID)
    rejection = "rejection off" if selected["rejection"] == "off" else f"reject {selected['reject']:.3g}"
    return (
        f"{selected['normalise']}/{selected['derived']}, {grid}, {rejection} "
        f"(validation {selected['validation_objective']:.3f})"
    )


def half_window(selected: dict) -> int:
    """Half the causal window behind a method's labels, in frames: the ``window`` of a scorer
    (MiniRocket, DTW, HMM; the scorer's for the CLM over it) or the ``delay`` window of the
    manifold methods (docs/segmentation.md, "Labels with a lag")."""
    return int(selected.get("window", selected.get("delay", 0))) // 2


class Report:
    """The reporting part of :class:`._recordings.RecordingsEvaluator`."""

    def _method_result(self, folds: list[FoldResult], name: str, truth: np.ndarray) -> dict:
        """The JSON entry of method ``name``: its figures pooled over ``folds`` and per fold."""
        pred = np.concatenate([f.labels[name] for f in folds])
        res = frame_metrics(truth, pred, self.known)
        res["segment_f1"] = segment_f1([(f.truth, f.labels[name]) for f in folds], self.known)
        res.update(self._at_lags(folds, name, truth))
        res["tradeoff_auc"] = None
        if name in folds[0].sweeps:  # the first value of every sweep keeps every frame
            res["no_rejection"] = frame_metrics(truth, np.concatenate([f.sweeps[name][0] for f in folds]), self.known)
        fell_back = [f for f in folds if name in f.strict]
        res["rejection_off_folds"] = len(fell_back)
        if fell_back:  # the objective's own choice, for the folds where it was overruled
            strict = np.concatenate([f.strict.get(name, f.labels[name]) for f in folds])
            res["strict"] = frame_metrics(truth, strict, self.known)
        where = "the folds themselves (preview)" if self.preview else "the inner folds"
        res["calibration_note"] = _fallback_note(len(folds), len(fell_back), res.get("strict"), where) or (
            _degenerate_calibration(
                truth, pred, self.known, [f.selected[name] for f in folds], res.get("no_rejection"), where
            )
        )
        if name in folds[0].sweeps and res["unknown_rejection"] is not None:
            res["tradeoff"] = self._tradeoff(folds, name, truth)
            res["tradeoff_auc"] = res["tradeoff"]["auc"]
        res["folds"] = [
            {
                "recording": f.recording,
                "untrained_classes": f.untrained,
                "selected": f.selected[name],
                **frame_metrics(f.truth, f.labels[name], self.known),
                "segment_f1": segment_f1([(f.truth, f.labels[name])], self.known),
                "half_window": half_window(f.selected[name]),
            }
            for f in folds
        ]
        if REGISTRY[name].batch is not None:
            batch = np.concatenate([f.labels[REGISTRY[name].batch.name] for f in folds])
            res["agreement"] = float(np.mean(pred == batch))
        if self.enroll:
            res["enrolment"] = enrolment_report(folds, name, self.known, self.enrol_adaptations)
        return res

    def _warnings(self, folds: list[FoldResult]) -> dict[str, int]:
        """The third-party warnings of every fold, counted by their gist and summarised once."""
        caught = sum((Counter(f.warnings) for f in folds), Counter())
        for line in summary(caught):
            self.progress(f"warned (summed over the folds): {line}")
        return dict(caught)

    def _at_lags(self, folds: list[FoldResult], name: str, truth: np.ndarray) -> dict:
        """Open-set frame accuracy and segment F1 at lag 0 and at half the method's causal window
        (per fold, :func:`half_window`): the latency/accuracy trade of :func:`..base.lagged`."""
        out: dict = {"open_set_accuracy_at_lag": {}, "segment_f1_at_lag": {}}
        for key, lag_of in (("0", lambda f: 0), ("half_window", lambda f: half_window(f.selected[name]))):
            pairs = [(f.truth, lagged(f.unlagged[name], lag_of(f))) for f in folds]
            out["open_set_accuracy_at_lag"][key] = frame_metrics(
                truth, np.concatenate([p for _, p in pairs]), self.known
            )["open_set_accuracy"]
            out["segment_f1_at_lag"][key] = segment_f1(pairs, self.known)
        return out

    def _tradeoff(self, folds: list[FoldResult], name: str, truth: np.ndarray) -> dict:
        n = min(len(f.sweeps[name]) for f in folds)
        acc, rej = [], []
        for i in range(n):  # the i-th value of every fold's own sweep (sweeps run from keep-all to reject-all)
            pred = np.concatenate([f.sweeps[name][round(i * (len(f.sweeps[name]) - 1) / max(n - 1, 1))] for f in folds])
            m = frame_metrics(truth, pred, self.known)
            acc.append(m["known_accuracy"] or 0.0)
            rej.append(m["unknown_rejection"] or 0.0)
        r, a, auc = tradeoff_curve(acc, rej)
        return {"unknown_rejection": r, "known_accuracy": a, "auc": auc}
