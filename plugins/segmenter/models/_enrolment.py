"""Recording models adapted to a session by its enrolment segments (docs/segmentation.md,
"Enrolment"), as the evaluation's ``--enroll`` adapts them: refitted as
:func:`._training.fit_recording_models` fitted them, on the session's first K segments per class
first and then the training recordings' segments; ``"align"`` standardises every recording
(training ones and the session) with its own enrolment frames first
(:func:`..datasets.session_alignment`), and the stream with the session's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..datasets import (
    ADAPTATIONS,
    MIN_SPREAD,
    DatasetError,
    EnrolmentError,
    Recording,
    enrolment_recording,
    load_recordings,
    segments,
    session_aligned,
    session_alignment,
)
from ._candidates import CandidateSet
from ._training import fit_recording_models


def _recordings(path: str | Path, classes: list[str]) -> list[Recording]:
    """The recordings at ``path`` labelled with indices into ``classes`` (other labels: unlabelled)."""
    data = load_recordings(path)
    lut = np.array([classes.index(c) if c in classes else -1 for c in data.class_names] + [-1])
    return [Recording(r.name, r.X, lut[r.y]) for r in data.recordings]


def enrolled_models(
    models: CandidateSet,
    training: str | Path,
    enrolment: str | Path,
    k: int = 1,
    adaptation: str = ADAPTATIONS[0],
    random_state: int | None = 0,
) -> tuple[CandidateSet, tuple[np.ndarray, np.ndarray] | None]:
    """``models`` refitted with the first ``k`` segments per class of the one recording at
    ``enrolment`` and the segments of their training recordings ``training`` (only the models'
    classes; the delay, derived features, scaling and training steps their provenance records; the
    calibrated background level kept), and the session's ``(offset, spread)`` that aligns the
    stream for ``"align"`` (None for ``"refit"``).  A DatasetError says what to change."""
    if adaptation not in ADAPTATIONS:
        raise ValueError(f"enroll_adaptation must be one of {ADAPTATIONS}, got {adaptation!r}")
    classes, known = models.classes, list(range(len(models.classes)))
    session, trained = _recordings(enrolment, classes), _recordings(training, classes)
    if len(session) != 1:
        raise DatasetError(f"{enrolment} holds {len(session)} recordings; enroll needs one recording of the session")
    alignment = None
    try:
        if adaptation == "align":
            floor = MIN_SPREAD * np.vstack([r.X for r in trained]).std(axis=0)
            alignment = session_alignment(session[0], known, k, floor)
            trained = [session_aligned(r, known, k, floor) for r in trained]
            session = [session_aligned(session[0], known, k, floor)]
        enrolled = enrolment_recording(session[0], known, k)[0]
    except EnrolmentError as exc:
        raise DatasetError(
            f"enroll: a recording has {exc}; record them, lower enroll_segments or set enroll_adaptation: refit"
        ) from None
    by_class = segments([enrolled, *trained], known)
    untrained = [classes[c] for c in known if not by_class[c]]
    if untrained:
        raise DatasetError(
            f"{training} holds no segment of {untrained}: name the recordings the models were trained on"
        )
    refit = fit_recording_models(
        {classes[c]: segs for c, segs in by_class.items()},
        delay=models.delay.window,
        n_steps=int(models.provenance.get("steps", 150)),
        random_state=random_state,
        scaling="none" if models.scaling is None else "standard",
        derived=models.derived.kind,
    )
    refit.background_factor, refit.history = models.background_factor, models.history
    return refit, alignment
