"""Open-set frame metrics, the rejection trade-off and its calibration (docs/segmentation.md).

Frames carry a true class index (``−1`` = unlabelled, ignored), a predicted index (``−1`` =
rejected) and a set of *known* classes; labelled frames of any other class are *unknown* and
must be rejected.  All figures are fractions in [0, 1]; a figure without frames is ``None``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np

from ..base import REJECTED, runs


def frame_metrics(truth: np.ndarray, pred: np.ndarray, known: Iterable[int]) -> dict:
    """``known_accuracy``, ``unknown_rejection``, ``open_set_accuracy`` and ``macro_f1``."""
    truth, pred = np.asarray(truth), np.asarray(pred)
    known = sorted({int(k) for k in known})
    labelled = truth >= 0
    is_known = labelled & np.isin(truth, known)
    is_unknown = labelled & ~is_known
    correct_known = is_known & (pred == truth)
    rejected_unknown = is_unknown & (pred == REJECTED)
    f1 = []
    for c in known:
        tp = np.sum(correct_known & (truth == c))
        fp = np.sum(labelled & (pred == c) & (truth != c))
        fn = np.sum(is_known & (truth == c) & (pred != c))
        if tp + fp + fn:
            f1.append(2 * tp / (2 * tp + fp + fn))
    return {
        "known_accuracy": _share(correct_known.sum(), is_known.sum()),
        "unknown_rejection": _share(rejected_unknown.sum(), is_unknown.sum()),
        "open_set_accuracy": _share(correct_known.sum() + rejected_unknown.sum(), labelled.sum()),
        "macro_f1": float(np.mean(f1)) if f1 else None,
    }


def segment_counts(truth: np.ndarray, pred: np.ndarray, known: Iterable[int], min_iou: float = 0.5) -> tuple:
    """``(matched, predicted, true)`` segment counts of one recording (see :func:`segment_f1`)."""
    truth, pred = np.asarray(truth), np.asarray(pred)
    target = np.where(np.isin(truth, sorted({int(k) for k in known})), truth, REJECTED)
    target = np.where(truth >= 0, target, -2)  # unlabelled frames: no true segment
    true = [t for t in runs(target) if t[0] != -2]
    labelled = np.r_[0, np.cumsum(truth >= 0)]
    predicted = [p for p in runs(pred) if labelled[p[2]] > labelled[p[1]]]
    matched, used = 0, set()
    for label, a, b in predicted:
        for i, (tl, ta, tb) in enumerate(true):
            if i in used or tl != label or tb <= a or ta >= b:
                continue
            if (min(b, tb) - max(a, ta)) / (max(b, tb) - min(a, ta)) >= min_iou:
                matched += 1
                used.add(i)
                break
    return matched, len(predicted), len(true)


def segment_f1(recordings: Iterable[tuple[np.ndarray, np.ndarray]], known: Iterable[int], min_iou: float = 0.5):
    """Segment F1 over recordings of ``(truth, pred)`` frame labels (docs/segmentation.md).

    Segments are maximal runs of one label within a recording.  True segments: runs of a known
    class keep their class, runs of unknown classes must be *rejected* (label ``−1``), unlabelled
    frames form no true segment.  Predicted segments: runs of the predicted label, a rejected run
    included; a run lying only on unlabelled frames is not counted.  A predicted segment matches
    an unmatched true one of the same label with intersection-over-union ≥ ``min_iou``;
    ``F1 = 2·matched / (predicted + true)``, ``None`` without segments.
    """
    counts = np.array([segment_counts(t, p, known, min_iou) for t, p in recordings]).reshape(-1, 3).sum(axis=0)
    return _share(2 * counts[0], counts[1] + counts[2])


def _share(num, den) -> float | None:
    return float(num) / float(den) if den else None


def threshold_labels(scores: np.ndarray, threshold: float) -> np.ndarray:
    """Winner per row of ``scores`` (higher = better); ``−1`` where the best score < ``threshold``."""
    return np.where(scores.max(axis=1) < threshold, REJECTED, np.argmax(scores, axis=1))


def tradeoff_curve(known_accuracy: Iterable[float], unknown_rejection: Iterable[float]) -> tuple[list, list, float]:
    """Points of a rejection sweep, closed at rejection 0 and 1, and their trapezoidal area.

    The sweep's points are sorted by rejection; the curve is extended to rejection 0 with the
    accuracy of the least-rejecting point and to rejection 1 with accuracy 0 (everything rejected)
    when the sweep does not reach those ends itself.
    """
    pts = sorted(zip(unknown_rejection, known_accuracy))
    rej = [p[0] for p in pts]
    acc = [p[1] for p in pts]
    if rej[0] > 0:
        rej.insert(0, 0.0)
        acc.insert(0, acc[0])
    if rej[-1] < 1:
        rej.append(1.0)
        acc.append(0.0)
    r, a = np.asarray(rej), np.asarray(acc)
    return rej, acc, float(np.sum(np.diff(r) * (a[1:] + a[:-1]) / 2))  # trapezoidal (np.trapezoid needs numpy 2)


def score_thresholds(confidence: np.ndarray, n: int = 41) -> np.ndarray:
    """A threshold sweep over a confidence's range: ``−inf`` (keep all), quantiles, ``+inf`` (reject all)."""
    qs = np.quantile(confidence[np.isfinite(confidence)], np.linspace(0, 1, n)) if confidence.size else []
    return np.unique(np.r_[-np.inf, qs, np.inf])


def calibrate(
    known_accuracy_at: Callable[[float], float],
    pseudo_rejection_at: Callable[[float], float],
    candidates: Iterable[float],
) -> tuple[float, float]:
    """The rejection parameter maximising ``(known_accuracy + pseudo-unknown rejection) / 2``.

    ``pseudo_rejection_at`` measures rejection of frames whose class was left out of the model —
    the validation stand-in for unknown motion.  Ties go to the first candidate.  ``candidates``
    run from keep-all to reject-all: the pseudo-unknown rejection (≤ 1) is only measured where it
    can still lift the objective above the best so far, and the search stops at the first value
    that rejects every known frame once the best objective is ≥ ½ (documented choice: stronger
    rejection cannot do better; it saved most of the CLM runs of the calibration).  Returns
    ``(parameter, objective)``.
    """
    best, best_j = None, -np.inf
    for value in candidates:
        known = known_accuracy_at(value)
        if best is not None and 0.5 * (known + 1.0) <= best_j:
            if known == 0.0 and best_j >= 0.5:
                break
            continue
        j = 0.5 * (known + pseudo_rejection_at(value))
        if j > best_j:
            best, best_j = value, j
    return best, float(best_j)
