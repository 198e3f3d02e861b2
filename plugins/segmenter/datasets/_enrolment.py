"""Enrolment: the first labelled segments of each known class at the start of a session
(docs/segmentation.md, "Enrolment").

A segment is a maximal run of one label of 2+ frames, as :func:`._recordings.segments` takes them.
The enrolment frames are the first ``k`` segments of each known class; the session's scored
frames are those after the last of them ends.  :func:`session_alignment` learns a session's
offset and scale from its enrolment frames (the ``align`` adaptation).
"""

from __future__ import annotations

import numpy as np

from ..base import runs
from ._recordings import UNLABELLED, Recording

ADAPTATIONS = ("align", "refit")  # how a session adapts to its enrolment; the first is the default
MIN_SPREAD = 0.1  # floor of an aligned channel's spread, in units of the training frames' (documented choice)


class EnrolmentError(ValueError):
    """A recording lacks the enrolment segments asked for."""


def enrolment_split(
    y: np.ndarray, classes: list[int], k: int, names: list[str] | None = None
) -> tuple[np.ndarray, int]:
    """Mask of the enrolment frames of labels ``y`` — the first ``k`` segments of every class
    in ``classes`` — and the first frame after them (the first scored frame).  Classes not in
    ``classes`` are never enrolled.  :class:`EnrolmentError` (naming classes by ``names``) when a
    class has fewer than ``k`` segments."""
    labels, starts, ends = np.array(runs(y), dtype=int).reshape(-1, 3).T
    long = ends - starts >= 2
    picked = [np.flatnonzero(long & (labels == c))[:k] for c in classes]
    short = [(names[c] if names else c, len(p)) for c, p in zip(classes, picked) if len(p) < k]
    if short:
        raise EnrolmentError(
            f"fewer segments than the {k} to enrol: " + ", ".join(f"class {c!r} has {n}" for c, n in short)
        )
    enrolled = np.concatenate(picked)
    edges = np.zeros(len(y) + 1, dtype=int)
    np.add.at(edges, starts[enrolled], 1)
    np.add.at(edges, ends[enrolled], -1)
    return np.cumsum(edges[:-1]) > 0, int(ends[enrolled].max(initial=0))


def enrolment_recording(rec: Recording, classes: list[int], k: int) -> tuple[Recording, int]:
    """The enrolment part of ``rec`` as a recording of its own — its frames up to the end of the
    enrolment, labelled only on the enrolment segments (:func:`enrolment_split`; other frames
    unlabelled, so never trained on) — and the first scored frame of ``rec``."""
    mask, end = enrolment_split(rec.y, classes, k)
    y = np.where(mask, rec.y, UNLABELLED)[:end]
    return Recording(f"{rec.name} (enrolment)", rec.X[:end], y), end


def session_alignment(
    rec: Recording, classes: list[int], k: int, min_spread: float | np.ndarray = MIN_SPREAD
) -> tuple[np.ndarray, np.ndarray]:
    """Per channel the class-balanced mean and spread of the enrolment frames of ``rec`` (each
    class of ``classes`` weighs alike, whatever its frames; the spread at least ``min_spread``):
    ``(rec.X − offset) / spread`` is the session aligned (docs/segmentation.md, "Enrolment")."""
    mask, _ = enrolment_split(rec.y, classes, k)
    frames = [rec.X[mask & (rec.y == c)] for c in classes]
    means = np.stack([f.mean(axis=0) for f in frames])
    spread = np.sqrt(np.mean([f.var(axis=0) for f in frames], axis=0) + means.var(axis=0))
    return means.mean(axis=0), np.maximum(spread, min_spread)


def session_aligned(
    rec: Recording, classes: list[int], k: int, min_spread: float | np.ndarray = MIN_SPREAD
) -> Recording:
    """``rec`` aligned by its own enrolment frames (:func:`session_alignment`)."""
    offset, spread = session_alignment(rec, classes, k, min_spread)
    return Recording(f"{rec.name} (aligned)", (rec.X - offset) / spread, rec.y)
