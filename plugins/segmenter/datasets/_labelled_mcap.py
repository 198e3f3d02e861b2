"""Labelled MCAP recordings → continuous recordings (``handflow dataset``, docs/segmentation.md, "From labelled recordings").

Every frame of the stream (a ``JointState`` or ``Array`` topic) takes the label of the interval
its stamp falls in (:mod:`handflow.framework.files.labels`): from a ``Label`` topic of the
recording (the cues of ``handflow collect``, or any other) or from a CSV of intervals.  The rest
between repetitions is the class :data:`REST`, which the dataset marks as unknown
(``unknown_classes``): ``evaluate segmentation`` counts its frames as unknown, to be rejected, and
``train-classes`` trains no model for it.  A session is cut into recordings of whole *rounds* (a
round ends once every class has had a repetition since the last cut; the cut lies where the next
repetition starts), so that leave one recording out works on one session.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from handflow.framework.files.labels import (
    Interval,
    LabelError,
    csv_intervals,
    frame_labels,
    read_interval_csv,
    topic_intervals,
)
from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.messages import Array, JointState, Label

from ._recordings import UNLABELLED

REST = "rest"
MIN_REPETITIONS = 3
"""Fewer repetitions of a class than this get a warning (documented choice: leave one recording out
needs a repetition to hold out and at least two to train on)."""


@dataclass
class Stream:
    """One recording's stream: stamps (ns), frames (T, D), column names, and the label intervals."""

    source: str
    stamps: np.ndarray
    X: np.ndarray
    columns: list[str]
    intervals: list[Interval] = field(default_factory=list)
    classes: list[str] = field(default_factory=list)  # as the cue topic names them (empty: unknown)


def read_stream(path: str | Path, topic: str, joints: Sequence[str] | None = None) -> tuple[Stream, dict]:
    """The frames of ``topic`` (NODE/PORT) and every ``Label`` topic's (stamp, label, classes) marks."""
    stamps, rows, columns = [], [], None
    marks: dict[str, list[tuple[int, str]]] = {}
    classes: dict[str, list[str]] = {}
    for rm in iter_recording(path):
        local = "/".join(rm.topic.split("/")[2:])
        if local == topic:
            msg = rm.decode()
            if isinstance(msg, JointState):
                names = list(msg.names)
                want = list(joints) if joints else names
                missing = [j for j in want if j not in names]
                if missing:
                    raise LabelError(f"{path}: {topic} lacks the joint(s) {missing}; it has {names}")
                rows.append(msg.positions[[names.index(j) for j in want]])
                columns = want
            elif isinstance(msg, Array):
                rows.append(np.asarray(msg.data, dtype=float).ravel())
                columns = columns or [f"x{i}" for i in range(rows[-1].size)]
            else:
                raise LabelError(f"{path}: {topic} carries {msg.TYPE}; label a JointState or Array stream")
            stamps.append(msg.header.stamp_ns)
        elif rm.type_name == Label.TYPE:
            msg = rm.decode()
            marks.setdefault(local, []).append((msg.header.stamp_ns, msg.label))
            if msg.classes and local not in classes:
                classes[local] = list(msg.classes)
    if not rows:
        raise LabelError(f"{path} holds no message on {topic}; name the recorded stream with --topic NODE/PORT")
    if len({r.size for r in rows}) != 1:
        raise LabelError(f"{path}: the frames of {topic} differ in size; record one layout per stream")
    order = np.argsort(np.asarray(stamps, dtype=np.int64), kind="stable")
    stream = Stream(str(path), np.asarray(stamps, dtype=np.int64)[order], np.stack(rows)[order], columns or [])
    return stream, {t: (m, classes.get(t, [])) for t, m in marks.items()}


def label_stream(stream: Stream, marks: dict, label_topic: str | None = None, csv: str | Path | None = None) -> Stream:
    """``stream`` with its intervals: from the CSV, or from ``label_topic`` (default: the only ``Label``
    topic named ``*/labels`` by a cue, else the only one); :class:`LabelError` when it has none."""
    if csv is not None:
        stream.intervals = csv_intervals(
            read_interval_csv(csv), int(stream.stamps[0]), int(stream.stamps[-1]), str(csv)
        )
        return stream
    if label_topic is None:
        cued = [t for t, (_, classes) in marks.items() if classes]
        candidates = cued if len(cued) == 1 else list(marks)
        if len(candidates) != 1:
            raise LabelError(
                f"{stream.source} carries no labels (no Label topic); record it with `handflow collect` or pass "
                f"--labels INTERVALS.csv"
                if not marks
                else f"{stream.source} has several Label topics ({', '.join(sorted(marks))}); choose one with --label-topic"
            )
        label_topic = candidates[0]
    if label_topic not in marks:
        raise LabelError(
            f"{stream.source} has no Label topic {label_topic}; it has {', '.join(sorted(marks)) or 'none'}"
        )
    found, stream.classes = marks[label_topic]
    stream.intervals = topic_intervals(found, int(stream.stamps[-1]) + 1)
    if not any(i.label != REST for i in stream.intervals):
        raise LabelError(f"{stream.source}: {label_topic} labels no repetition of a class (only rest or nothing)")
    return stream


def round_cuts(intervals: Sequence[Interval], classes: Sequence[str], rounds: int = 1) -> list[int]:
    """Stamps where a new recording starts: after every ``rounds`` rounds (module docstring)."""
    cuts, seen, done = [], set(), 0
    pending = False
    for i in intervals:
        if i.label == REST:
            continue
        if pending:
            cuts.append(i.start_ns)
            pending = False
        seen.add(i.label)
        if set(classes) <= seen:
            seen, done = set(), done + 1
            pending = done % rounds == 0
    return cuts


@dataclass
class Dataset:
    """Continuous recordings in the layout of :func:`._recordings.load_recordings` (``.npz``) and what they hold."""

    arrays: dict[str, np.ndarray]
    frames: dict[str, int]
    repetitions: dict[str, int]
    recordings: int

    def save(self, out: str | Path) -> Path:
        out = Path(out)
        out.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(out, **self.arrays)
        return out


def build_dataset(streams: Sequence[Stream], classes: Sequence[str] | None = None, rounds: int = 1) -> Dataset:
    """The continuous dataset of labelled ``streams``: class names = ``classes`` (default: those the cues
    name, else every label) then :data:`REST`; a class without a repetition is a :class:`LabelError`."""
    if len({tuple(s.columns) for s in streams}) != 1:
        raise LabelError("the recordings' streams have different columns; pass the same --joints for all")
    named = list(classes or next((s.classes for s in streams if s.classes), []))
    labels = sorted({i.label for s in streams for i in s.intervals} - {REST})
    names = [c for c in (named or labels) if c != REST]
    reps = Counter(i.label for s in streams for i in s.intervals if _holds_frames(s, i))
    missing = [c for c in names if reps[c] == 0]
    if missing:
        raise LabelError(
            f"class(es) {missing} have no repetition in the recordings; record them (`handflow collect --append`) "
            f"or leave them out with --classes"
        )
    class_names = [*names, REST]
    index = {c: k for k, c in enumerate(class_names)}
    arrays: dict[str, np.ndarray] = {}
    frames: Counter = Counter()
    n_rec = 0
    stems = Counter(Path(s.source).stem for s in streams)
    for k, s in enumerate(streams):
        stem = Path(s.source).stem if stems[Path(s.source).stem] == 1 else f"{Path(s.source).stem}{k}"
        labels = frame_labels(s.stamps, s.intervals)
        y = np.array([index.get(lab, UNLABELLED) for lab in labels], dtype=int)
        bounds = np.searchsorted(s.stamps, round_cuts(s.intervals, names, rounds))
        for r, (lo, hi) in enumerate(zip(np.r_[0, bounds], np.r_[bounds, len(y)])):
            if hi - lo < 2:
                continue
            name = f"{stem}_r{r}"
            arrays[f"X_{name}"] = s.X[lo:hi]
            arrays[f"y_{name}"] = y[lo:hi]
            arrays[f"t_{name}"] = (s.stamps[lo:hi] - s.stamps[0]) / 1e9
            n_rec += 1
        frames.update(class_names[c] for c in y[y >= 0])
    arrays["class_names"] = np.array(class_names)
    arrays["unknown_classes"] = np.array([REST])
    meta = {"columns": streams[0].columns, "sources": [s.source for s in streams], "rounds_per_recording": rounds}
    arrays["metadata"] = np.array(json.dumps(meta))
    return Dataset(arrays, {c: frames[c] for c in class_names}, {c: reps[c] for c in class_names}, n_rec)


def _holds_frames(stream: Stream, interval: Interval) -> bool:
    lo, hi = np.searchsorted(stream.stamps, [interval.start_ns, interval.end_ns])
    return hi - lo >= 2
