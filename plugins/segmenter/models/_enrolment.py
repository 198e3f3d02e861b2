"""Recording models adapted to a session by its enrolment segments (docs/segmentation.md,
"Enrolment"): refitted as :func:`._training.fit_recording_models` fitted them, on the enrolment
segments first and then the training segments — the same rule as the evaluation's ``--enroll``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..datasets import DatasetError, load_recordings, segments
from ._candidates import CandidateSet
from ._training import fit_recording_models


def class_segments(path: str | Path, classes: list[str]) -> dict[str, list[np.ndarray]]:
    """Class name → the labelled segments (2+ frames) of ``classes`` in the recordings at ``path``
    (a folder of labelled CSVs or a continuous .npz); classes the recordings lack get none."""
    data = load_recordings(path)
    held = [c for c in classes if c in data.class_names]
    segs = segments(data.recordings, [data.class_names.index(c) for c in held])
    return {c: segs.get(data.class_names.index(c), []) if c in held else [] for c in classes}


def enrolled_models(
    models: CandidateSet, training: str | Path, enrolment: str | Path, random_state: int | None = 0
) -> CandidateSet:
    """``models`` refitted on the segments of their classes in the recordings ``enrolment`` (a
    short labelled recording of the session; only the models' classes are enrolled) and in their
    training recordings ``training``, with the delay, derived features, scaling and training steps
    their provenance records; the background level stays the one calibrated for ``models``."""
    classes = models.classes
    enrolled, trained = class_segments(enrolment, classes), class_segments(training, classes)
    if not any(enrolled.values()):
        raise DatasetError(f"{enrolment} holds no labelled segment of the models' classes {classes}")
    untrained = [c for c in classes if not trained[c]]
    if untrained:
        raise DatasetError(
            f"{training} holds no segment of {untrained}: name the recordings the models were trained on"
        )
    provenance = next(iter(models.models.values())).model.provenance_
    refit = fit_recording_models(
        {c: enrolled[c] + trained[c] for c in classes},
        delay=models.delay.window,
        n_steps=int(provenance.get("steps", 150)),
        random_state=random_state,
        scaling="none" if models.scaling is None else "standard",
        derived=models.derived.kind,
    )
    refit.background_factor = models.background_factor
    return refit
