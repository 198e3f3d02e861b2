"""Labels a recording carries: intervals from a ``Label`` topic or from a CSV of intervals (docs/recording.md, "Labels").

A ``Label`` topic labels time: each message labels from its stamp until the next message's stamp
(the last one until the end of the labelled stream), so a sparse marker stream (the cues of
``handflow collect``, as Lab Streaming Layer markers sit beside the data) and a label per sample
(``segmenter/labels``) read alike.  The empty label ``""`` marks time as unlabelled.  Of several
messages with the same stamp the one received last counts: ``handflow collect`` withdraws an
interrupted repetition so, with an empty label at that repetition's stamp.  Neighbouring intervals
of one label are merged.

A CSV of intervals has rows ``start_s,end_s,label`` (an optional header ``start_s,end_s,label``),
in seconds from the first message on the labelled topic, as ``time_ranges`` in training configs
count them (docs/training.md); the intervals may not overlap and must lie within the recording.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

CSV_HEADER = ("start_s", "end_s", "label")
EDGE_TOLERANCE_S = 0.05
"""How far (seconds) an interval of a CSV may reach beyond the labelled stream (documented choice:
one frame at 20 Hz, so an interval typed to the recording's rounded length is kept)."""


class LabelError(ValueError):
    """Labels that cannot be used, with what to change."""


@dataclass(frozen=True)
class Interval:
    """``label`` from ``start_ns`` (inclusive) to ``end_ns`` (exclusive)."""

    start_ns: int
    end_ns: int
    label: str


def topic_intervals(marks: Iterable[tuple[int, str]], end_ns: int) -> list[Interval]:
    """Intervals of ``(stamp_ns, label)`` messages in the order received (module docstring); ``end_ns``
    closes the last one."""
    latest: dict[int, str] = {}
    for stamp, label in marks:
        latest[int(stamp)] = label  # the last received of one stamp counts
    stamps = sorted(latest)
    out: list[Interval] = []
    for k, stamp in enumerate(stamps):
        stop = stamps[k + 1] if k + 1 < len(stamps) else max(int(end_ns), stamp)
        label = latest[stamp]
        if not label or stop <= stamp:
            continue
        if out and out[-1].label == label and out[-1].end_ns == stamp:
            out[-1] = Interval(out[-1].start_ns, stop, label)
        else:
            out.append(Interval(stamp, stop, label))
    return out


@dataclass(frozen=True)
class CsvInterval:
    """One row of an interval CSV: seconds from the first message on the labelled topic, and its line."""

    start_s: float
    end_s: float
    label: str
    line: int


def parse_interval_csv(text: str, source: str = "intervals") -> list[CsvInterval]:
    """The rows of an interval CSV, sorted by start; :class:`LabelError` (``source:line``) for a row
    that is not ``start_s,end_s,label`` with finite ``start_s < end_s`` and a label, or for overlaps."""
    try:
        table = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as exc:
        raise LabelError(f"{source}: not a CSV of start_s,end_s,label rows ({exc})") from None
    rows: list[CsvInterval] = []
    for line, row in enumerate(table, 1):
        cells = [c.strip() for c in row]
        if not any(cells) or cells[0].startswith("#"):
            continue
        if not rows and tuple(c.lower() for c in cells) == CSV_HEADER:
            continue
        if len(cells) != 3:
            raise LabelError(f"{source}:{line}: expected start_s,end_s,label, got {len(cells)} value(s)")
        try:
            start, end = float(cells[0]), float(cells[1])
        except ValueError:
            raise LabelError(f"{source}:{line}: start_s and end_s must be numbers (seconds), got {row[:2]}") from None
        if not (math.isfinite(start) and math.isfinite(end)) or start < 0 or end <= start:
            raise LabelError(f"{source}:{line}: need 0 <= start_s < end_s (seconds), got {cells[0]}, {cells[1]}")
        if not cells[2]:
            raise LabelError(f"{source}:{line}: the label is empty; name the class of the interval")
        rows.append(CsvInterval(start, end, cells[2], line))
    if not rows:
        raise LabelError(f"{source} holds no interval; write rows start_s,end_s,label")
    rows.sort(key=lambda r: (r.start_s, r.end_s))
    for a, b in zip(rows, rows[1:]):
        if b.start_s < a.end_s:
            raise LabelError(
                f"{source}:{b.line}: interval {b.start_s:g}–{b.end_s:g} s overlaps {a.start_s:g}–{a.end_s:g} s "
                f"of line {a.line}; a frame has one label: shorten or remove one of them"
            )
    return rows


def read_interval_csv(path: str | Path) -> list[CsvInterval]:
    """:func:`parse_interval_csv` of a file."""
    try:
        text = Path(path).read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise LabelError(f"cannot read the interval file {path}: {exc}") from None
    return parse_interval_csv(text, str(path))


def csv_intervals(
    rows: Sequence[CsvInterval], first_ns: int, last_ns: int, source: str = "intervals"
) -> list[Interval]:
    """Rows placed on a stream whose first message has stamp ``first_ns`` and last ``last_ns``; a
    row beyond the stream (by more than :data:`EDGE_TOLERANCE_S`) is a :class:`LabelError`."""
    length_s = (last_ns - first_ns) / 1e9
    for r in rows:
        if r.end_s > length_s + EDGE_TOLERANCE_S:
            raise LabelError(
                f"{source}:{r.line}: interval {r.start_s:g}–{r.end_s:g} s ends after the labelled stream, which "
                f"lasts {length_s:.2f} s; give seconds from the stream's first message"
            )
    return [Interval(first_ns + round(r.start_s * 1e9), first_ns + round(r.end_s * 1e9), r.label) for r in rows]


def frame_labels(stamps_ns: np.ndarray, intervals: Sequence[Interval]) -> np.ndarray:
    """The label of every stamp (``""`` outside every interval); intervals must not overlap."""
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    out = np.full(len(stamps), "", dtype=object)
    if not intervals:
        return out
    starts = np.array([i.start_ns for i in intervals], dtype=np.int64)
    ends = np.array([i.end_ns for i in intervals], dtype=np.int64)
    order = np.argsort(starts, kind="stable")
    starts, ends = starts[order], ends[order]
    labels = np.array([intervals[k].label for k in order], dtype=object)
    k = np.searchsorted(starts, stamps, side="right") - 1
    inside = (k >= 0) & (stamps < ends[np.maximum(k, 0)])
    out[inside] = labels[k[inside]]
    return out


def summarize_intervals(intervals: Sequence[Interval]) -> dict[str, dict[str, float]]:
    """Per label: how many intervals and how many seconds (``handflow inspect``)."""
    out: dict[str, dict[str, float]] = {}
    for i in intervals:
        entry = out.setdefault(i.label, {"intervals": 0, "seconds": 0.0})
        entry["intervals"] += 1
        entry["seconds"] = round(entry["seconds"] + (i.end_ns - i.start_ns) / 1e9, 3)
    return dict(sorted(out.items()))


def recognition_shares(
    path: str | Path,
    truth_topic: str,
    labels_topic: str,
    truth_path: str | Path | None = None,
    revisions: bool = True,
) -> dict[str, dict[str, float]]:
    """How the per-frame labels on ``labels_topic`` (a recogniser's, ``NODE/PORT``) match the truth
    on ``truth_topic`` (a ``Label`` topic, e.g. ``glove/performed``), per true label: ``frames``, the
    share labelled that label (``right``) and the share labelled ``unknown``.  With ``revisions`` the
    recogniser's revision events (``SegmentEvent`` on the labels' ``events`` port) are applied first,
    so the shares are those of its final labels, else of its labels on arrival; the truth may come
    from another recording (``truth_path``, e.g. the live run a lock-step replay recomputed)."""
    from .mcap_reader import iter_recording

    events_topic = labels_topic.rsplit("/", 1)[0] + "/events"
    marks, stamps, labels, by_index, revised = [], [], [], {}, []
    for rm in iter_recording(truth_path or path, [truth_topic]):
        msg = rm.decode()
        marks.append((msg.header.stamp_ns, msg.label))
    for rm in iter_recording(path, [labels_topic, events_topic]):
        msg = rm.decode()
        if rm.topic.endswith("/" + labels_topic):
            by_index[msg.index] = len(labels)
            stamps.append(msg.header.stamp_ns)
            labels.append(msg.label)
        elif revisions and getattr(msg, "kind", "") == "revision":
            revised.append(msg)
    for ev in revised:
        for i in range(ev.start_index, ev.end_index + 1):
            if i in by_index:
                labels[by_index[i]] = ev.label
    if not marks or not labels:
        raise LabelError(f"{path}: no truth on {truth_topic} or no labels on {labels_topic}")
    truth = frame_labels(np.array(stamps), topic_intervals(marks, max(stamps) + 1))
    got = np.array(labels, dtype=object)
    out = {}
    for label in sorted(set(truth) - {""}):
        here = truth == label
        out[label] = {
            "frames": int(here.sum()),
            "right": round(float((got[here] == label).mean()), 4),
            "unknown": round(float((got[here] == "unknown").mean()), 4),
        }
    return out
