"""Enrolment in the leave-one-recording-out protocol (docs/segmentation.md, "Enrolment").

With ``enroll`` = K ≥ 1, every fold's held-out recording starts with the first K segments of
each known class (:func:`..datasets.enrolment_split`).  Every method is fitted once more with
those segments as one more training recording, put first (its other frames unlabelled), with the
parameters and rejection value chosen without them on the inner folds; the UKR class models are
thereby refitted with the enrolment segments (documented choice).  Both fits label the whole
held-out recording, scaled with the other recordings' frames only, and both are scored on the
same frames: those after the enrolment.
"""

from __future__ import annotations

import numpy as np

from ..datasets import EnrolmentError, RecordingSet, enrolment_split
from ._metrics import frame_metrics


def check_enrolment(data: RecordingSet, known: list[int], k: int) -> None:
    """A ValueError that says what to change when some recording cannot be a held-out one with
    ``k`` enrolment segments of every known class (the evaluation then stops before any fold)."""
    if k < 0:
        raise ValueError(f"--enroll must be >= 0 segments per class, got {k}")
    for rec in data.recordings:
        try:
            enrolment_split(rec.y, known, k, data.class_names)
        except EnrolmentError as exc:
            raise ValueError(
                f"--enroll {k}: recording '{rec.name}' has {exc}; lower --enroll, or leave such classes "
                "out with --known (docs/segmentation.md, Enrolment)"
            ) from None


def enrolment_report(folds: list, name: str, known: list[int]) -> dict:
    """Frame metrics of ``name`` with and without enrolment on the same frames (each fold's frames
    after its enrolment, pooled), the gain in open-set accuracy and the scored frames per fold."""

    def pooled(labels_of) -> dict:
        return frame_metrics(
            np.concatenate([f.truth[f.scored_from :] for f in folds]),
            np.concatenate([labels_of(f)[f.scored_from :] for f in folds]),
            known,
        )

    with_, without = pooled(lambda f: f.enrolled[name]), pooled(lambda f: f.labels[name])
    a, b = with_["open_set_accuracy"], without["open_set_accuracy"]
    return {
        "open_set_accuracy": a,
        "open_set_accuracy_without_enrolment": b,
        "gain": None if a is None or b is None else a - b,
        "with_enrolment": with_,
        "without_enrolment": without,
        "scored_from": {f.recording: f.scored_from for f in folds},
    }
