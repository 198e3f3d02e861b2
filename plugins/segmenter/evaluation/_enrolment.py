"""Enrolment in the leave-one-recording-out protocol (docs/segmentation.md, "Enrolment").

With ``enroll`` = K ≥ 1, every fold's held-out recording starts with the first K segments of
each known class (:func:`..datasets.enrolment_split`).  Every method is fitted once more with
those segments as one more training recording, put first (its other frames unlabelled), with the
parameters and rejection value chosen without them on the inner folds.  Adaptations
(:data:`EVALUATION_ADAPTATIONS`): ``"align"`` also standardises every recording of the fold with the
class-balanced mean and spread of its own enrolment frames (a per-session alignment of scale and
offset, :func:`..datasets.session_alignment`; the recordings are scaled with the training frames
already, so the spread's floor is a tenth of theirs); ``"refit"`` adds the segments only;
``"chosen"`` (the default) takes, per method and fold, whichever of :data:`ENROL_CHOICES` labels
the inner folds' frames after their own enrolment best (``"none"``: the fit without enrolment),
an adaptation only when it beats no enrolment there by :data:`ENROL_MARGIN`.
Both fits label the whole held-out recording and are scored on the same frames: those after the
enrolment.
"""

from __future__ import annotations

import numpy as np

from ..base import lagged
from ..datasets import (
    ADAPTATIONS,
    EnrolmentError,
    RecordingSet,
    enrolment_recording,
    enrolment_split,
    session_aligned,
)
from ._calibration import Choice, inner_folds
from ._fidelity import REFINE
from ._methods import REGISTRY
from ._metrics import frame_metrics

CHOSEN = "chosen"  # the adaptation chosen per method and fold on the inner folds
ENROL_CHOICES = ("none", "refit", "align")  # what CHOSEN chooses among; ties keep the first
ENROL_MARGIN = 0.05  # an adaptation must beat no enrolment on the inner folds by this much (documented choice)
EVALUATION_ADAPTATIONS = (CHOSEN, *ADAPTATIONS)  # the first is the evaluation's default


def check_enrolment(data: RecordingSet, known: list[int], k: int, adaptations: tuple[str, ...]) -> None:
    """A ValueError that says what to change when some recording cannot be a held-out one with
    ``k`` enrolment segments of every known class (the evaluation then stops before any fold)."""
    if k < 0:
        raise ValueError(f"--enroll must be >= 0 segments per class, got {k}")
    if (
        not adaptations
        or len(set(adaptations)) != len(adaptations)
        or not set(adaptations) <= set(EVALUATION_ADAPTATIONS)
    ):
        raise ValueError(
            f"enrolment adaptations: name distinct choices among {EVALUATION_ADAPTATIONS}, got {list(adaptations)}"
        )
    for rec in data.recordings:
        try:
            if enrolment_split(rec.y, known, k, data.class_names)[1] == len(rec.y):
                raise EnrolmentError("no frame after its enrolment segments")
        except EnrolmentError as exc:
            raise ValueError(
                f"--enroll {k}: recording '{rec.name}' has {exc}; lower --enroll, or leave such classes "
                "out with --known (docs/segmentation.md, Enrolment)"
            ) from None


def enrolled(train: list, test, known: list[int], k: int, adaptation: str) -> tuple[list, object]:
    """The training recordings with ``test``'s enrolment first, and ``test``; every recording
    aligned by its own enrolment for ``"align"``; both unchanged for ``"none"``."""
    if adaptation == "none":
        return train, test
    if adaptation == "align":
        train, test = [session_aligned(r, known, k) for r in train], session_aligned(test, known, k)
    return [enrolment_recording(test, known, k)[0], *train], test


def enrolled_views(views: dict, known: list[int], k: int, adaptation: str) -> dict:
    """:func:`enrolled` per normalisation and derived feature choice (``views``: → training
    recordings, held-out recording)."""
    return {key: enrolled(train, test, known, k, adaptation) for key, (train, test) in views.items()}


def enrolment_report(folds: list, name: str, known: list[int], adaptations: tuple[str, ...]) -> dict:
    """Frame metrics of ``name`` with (per adaptation; the first one's at the top) and without
    enrolment on the same frames (each fold's frames after its enrolment, pooled), the gains in
    open-set accuracy, the first scored frame per fold and, for ``"chosen"``, each fold's choice."""

    def pooled(labels_of) -> dict:
        return frame_metrics(
            np.concatenate([f.truth[f.scored_from :] for f in folds]),
            np.concatenate([labels_of(f)[f.scored_from :] for f in folds]),
            known,
        )

    without = pooled(lambda f: f.labels[name])
    by = {}
    for a in adaptations:
        with_ = pooled(lambda f, a=a: f.enrolled[a][name])
        gain = (
            None
            if None in (with_["open_set_accuracy"], without["open_set_accuracy"])
            else (with_["open_set_accuracy"] - without["open_set_accuracy"])
        )
        by[a] = {"open_set_accuracy": with_["open_set_accuracy"], "gain": gain, "with_enrolment": with_}
        if a == CHOSEN:  # what the inner folds chose, per fold
            by[a]["chosen"] = {f.recording: f.selected[name]["enrol_adaptation"] for f in folds}
    return {
        "adaptation": adaptations[0],
        **by[adaptations[0]],
        "open_set_accuracy_without_enrolment": without["open_set_accuracy"],
        "without_enrolment": without,
        "adaptations": by,
        "scored_from": {f.recording: f.scored_from for f in folds},
    }


def fold_note(fold, known: list[int]) -> str:
    """One fold's open-set accuracy per method on its frames after the enrolment, with enrolment
    (per adaptation) and without, for the progress log."""

    def accuracy(labels: np.ndarray) -> str:
        value = frame_metrics(fold.truth[fold.scored_from :], labels[fold.scored_from :], known)["open_set_accuracy"]
        return "—" if value is None else f"{value:.3f}"

    figures = "; ".join(
        f"{name} {', '.join(f'{accuracy(by[name])} ({a})' for a, by in fold.enrolled.items())}, "
        f"{accuracy(fold.labels[name])} without"
        for name in fold.labels
    )
    return f"{fold.recording}: after the enrolment (from frame {fold.scored_from}): {figures}"


class EnrolmentFits:
    """The enrolment part of :class:`._recordings.RecordingsEvaluator`: the fits with the held-out
    recording's enrolment and the choice of adaptation on the inner folds."""

    def _enrolled(self, method, choice: Choice, session: dict) -> dict[str, np.ndarray]:
        """The lagged labels of the held-out recording by ``method`` (and the online methods that
        replay its models) with ``choice``, fitted with the enrolment (``session``:
        :func:`._enrolment.enrolled_views`)."""
        fitted, state, test = self._final(method, choice.params, session)
        out = {method.name: method.labels(fitted, state, choice.reject)}
        for online in map(REGISTRY.get, self._replaying(method)):
            out[online.name] = online.labels_online(fitted, choice.reject, test.X)
        return {name: lagged(x, self.lag) for name, x in out.items()}

    def _adaptation(self, method, choice: Choice, views) -> tuple[str, dict[str, float]]:
        """The enrolment adaptation (:data:`._enrolment.ENROL_CHOICES`) of ``method`` with
        ``choice``, and each one's open-set accuracy on the inner folds' frames after their own
        enrolment (pooled): each inner validation recording enrols as the held-out one does,
        refitted on the other training recordings.  The best one, if it beats no enrolment by
        :data:`._enrolment.ENROL_MARGIN` (ties keep the first); no enrolment otherwise."""
        train = views[choice.params["normalise"], choice.params["derived"]][0]
        folds = inner_folds(train)
        starts = [enrolment_split(v.y, self.known, self.enroll)[1] for v, _ in folds]
        truth = np.concatenate([v.y[s:] for (v, _), s in zip(folds, starts)])
        scores = {}
        for adaptation in ENROL_CHOICES:
            pred = []
            for (v, rest), start in zip(folds, starts):
                fit_on, test = enrolled(rest, v, self.known, self.enroll, adaptation)
                fitted = self._fit(method, fit_on, choice.params, REFINE)
                labels = method.labels(fitted, self._prepare(method, fitted, test), choice.reject)
                pred.append(lagged(labels, self.lag)[start:])
            scores[adaptation] = frame_metrics(truth, np.concatenate(pred), self.known)["open_set_accuracy"] or 0.0
        best = max(ENROL_CHOICES, key=scores.get)
        if scores[best] < scores[ENROL_CHOICES[0]] + ENROL_MARGIN:
            best = ENROL_CHOICES[0]
        self.progress(
            f"    {method.name}: enrolment {best} ("
            + ", ".join(f"{a} {score:.3f}" for a, score in scores.items())
            + f" on the inner folds' frames after their enrolment; an adaptation must gain {ENROL_MARGIN})"
        )
        return best, scores
