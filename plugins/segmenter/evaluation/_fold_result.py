"""What a fold of the leave-one-recording-out protocol gives (docs/segmentation.md, "reading the
output"): each batch method's part of a fold (:class:`MethodFold`, what ``--cache`` keeps), the
whole fold (:class:`FoldResult`, what ``--checkpoints`` keeps and the report reads) and the
seconds per method and phase (:func:`timing`).  Data only: the runner (:mod:`._folds`), the
preview (:mod:`._preview`) and the report (:mod:`._report`) build on it."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class MethodFold:
    """One batch method's part of a fold (with the online methods that replay its models): what
    ``--cache`` keeps per method and fold."""

    recording: str
    method: str
    labels: dict[str, np.ndarray]  # per method, at lag 0
    selected: dict[str, dict]
    sweeps: list[np.ndarray]  # the batch method's labels at every rejection value of its sweep (lagged)
    strict: np.ndarray | None  # its labels at the strict choice where it fell back (lagged)
    enrolled: dict[str, dict[str, np.ndarray]]  # per adaptation, method: labels (lagged)
    timing: dict[str, dict[str, float]]  # method → phase → seconds
    warnings: dict[str, int] = field(default_factory=dict)  # third-party warnings while computing it


@dataclass
class FoldResult:
    recording: str
    truth: np.ndarray
    labels: dict[str, np.ndarray]
    selected: dict[str, dict]
    sweeps: dict[str, list[np.ndarray]]  # per method: labels at every rejection value of its sweep
    strict: dict[str, np.ndarray]  # per method that fell back: the labels at the strict choice
    untrained: list[str]  # known classes without a training segment in this fold
    unlagged: dict[str, np.ndarray]  # per method: the labels at lag 0 (``labels`` are at the evaluation's lag)
    enrolled: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)  # per adaptation, method: labels
    scored_from: int = 0  # the first frame after the enrolment
    seconds: float = 0.0  # the fold's own wall time
    timing: dict[str, dict[str, float]] = field(default_factory=dict)  # method → phase → seconds
    warnings: dict[str, int] = field(default_factory=dict)  # third-party warnings of its methods: gist → count


def timing(folds: list[FoldResult]) -> dict:
    """Seconds per method and phase (selection, final fit, labelling), summed over the folds, and
    each fold's wall time: the JSON's ``timing`` (on the machine of the run, unlike the figures)."""
    per_method: dict[str, dict[str, float]] = {}
    for fold in folds:
        for name, phases in fold.timing.items():
            for phase, seconds in phases.items():
                per_method.setdefault(name, {}).setdefault(phase, 0.0)
                per_method[name][phase] += seconds
    return {
        "methods": {n: {p: round(v, 2) for p, v in phases.items()} for n, phases in per_method.items()},
        "folds": {f.recording: round(f.seconds, 2) for f in folds},
    }
