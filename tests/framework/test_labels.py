"""Labels of a recording: interval CSVs and Label topics (framework/files/labels.py), the cue order of
``handflow collect`` (framework/recorder/cues.py) and ``--set`` overrides."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from handflow.framework.files.labels import (
    Interval,
    LabelError,
    csv_intervals,
    frame_labels,
    parse_interval_csv,
    topic_intervals,
)
from handflow.framework.graphs.overrides import OverrideError, graph_text_with, parse_set
from handflow.framework.recorder.cues import check_classes, schedule

REPO = Path(__file__).resolve().parents[2]
labels = st.sampled_from(["", "rest", "grasp", "pinch", "wave"])


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=300))
def test_any_csv_text_parses_or_says_what_to_change(text):
    try:
        rows = parse_interval_csv(text, "f.csv")
    except LabelError as exc:
        assert str(exc).startswith("f.csv")
        return
    assert rows and all(0 <= r.start_s < r.end_s and r.label for r in rows)
    assert all(a.end_s <= b.start_s for a, b in zip(rows, rows[1:]))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 100), st.floats(0.01, 10), labels.filter(bool)), min_size=1, max_size=8))
def test_csv_rows_round_trip_and_overlaps_are_refused(rows):
    text = "start_s,end_s,label\n" + "".join(f"{s!r},{s + d!r},{lab}\n" for s, d, lab in rows)
    spans = sorted((s, s + d) for s, d, _ in rows)
    overlapping = any(b[0] < a[1] for a, b in zip(spans, spans[1:]))
    if overlapping:
        with pytest.raises(LabelError, match="overlaps"):
            parse_interval_csv(text)
        return
    parsed = parse_interval_csv(text)
    assert sorted((r.start_s, r.end_s, r.label) for r in parsed) == sorted((s, s + d, lab) for s, d, lab in rows)


def test_csv_errors_name_the_line():
    with pytest.raises(LabelError, match="f.csv:2: .*numbers"):
        parse_interval_csv("start_s,end_s,label\nx,2,a\n", "f.csv")
    with pytest.raises(LabelError, match="f.csv:1: need 0 <= start_s < end_s"):
        parse_interval_csv("3,2,a\n", "f.csv")
    with pytest.raises(LabelError, match="label is empty"):
        parse_interval_csv("1,2,\n", "f.csv")
    with pytest.raises(LabelError, match="f.csv:3: interval 1.5–3 s overlaps 1–2 s of line 2"):
        parse_interval_csv("start_s,end_s,label\n1,2,a\n1.5,3,b\n", "f.csv")
    with pytest.raises(LabelError, match="holds no interval"):
        parse_interval_csv("start_s,end_s,label\n", "f.csv")
    rows = parse_interval_csv("0,1,a\n1,2.04,b\n")
    assert [i.end_ns for i in csv_intervals(rows, 10**9, 3 * 10**9)] == [2 * 10**9, int(3.04e9)]
    with pytest.raises(LabelError, match="ends after the labelled stream, which lasts 1.00 s"):
        csv_intervals(rows, 0, 10**9, "f.csv")


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 50), labels), max_size=30), st.integers(0, 60))
def test_label_topic_intervals_follow_the_last_message_of_each_stamp(marks, end):
    intervals = topic_intervals(marks, end)
    latest = dict(marks)
    for i in intervals:
        assert i.label and i.start_ns < i.end_ns
    assert all(a.end_ns <= b.start_ns for a, b in zip(intervals, intervals[1:]))
    assert all(not (a.end_ns == b.start_ns and a.label == b.label) for a, b in zip(intervals, intervals[1:]))
    stamps = np.arange(0, 61)
    got = frame_labels(stamps, intervals)
    for t, lab in zip(stamps, got):  # brute force: the label of the latest stamp at or before t
        before = [s for s in latest if s <= t]
        want = latest[max(before)] if before and (t < max(end, max(before)) or t < max(latest)) else ""
        if before and t >= max(latest) and t >= end:
            want = ""
        assert lab == want, (t, lab, want)


def test_an_interrupted_repetition_is_withdrawn_at_its_stamp():
    marks = [(0, "rest"), (10, "grasp"), (20, "rest"), (30, "pinch"), (30, ""), (35, "")]
    assert topic_intervals(marks, 40) == [Interval(0, 10, "rest"), Interval(10, 20, "grasp"), Interval(20, 30, "rest")]


def test_cue_rounds_are_seeded_permutations_and_append_continues_them():
    classes = ["grasp", "pinch", "wave", "fist"]
    cues = list(schedule(classes, 5, seed=3))
    assert [c.index for c in cues] == list(range(20))
    for r in range(5):
        assert sorted(c.label for c in cues if c.round == r) == sorted(classes)
    assert len({tuple(c.label for c in cues if c.round == r) for r in range(5)}) > 1
    assert list(schedule(classes, 2, seed=3, first_round=3)) == cues[12:20]
    assert cues != list(schedule(classes, 5, seed=4))
    for bad in (["rest"], ["a", "a"], ["a_b"], [""]):
        with pytest.raises(ValueError, match="--classes"):
            check_classes(bad)


def test_set_resolves_input_paths_against_the_current_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    text = graph_text_with("recognise_gestures", ["segmenter.models=my_models", "segmenter.window=80"])
    import yaml

    params = next(n for n in yaml.safe_load(text)["nodes"] if n["id"] == "segmenter")["params"]
    assert params["models"] == str(tmp_path / "my_models") and params["window"] == 80
    with pytest.raises(OverrideError, match="no node 'segmentr'"):
        graph_text_with("recognise_gestures", ["segmentr.models=x"])
    with pytest.raises(OverrideError, match="NODE.KEY=VALUE"):
        parse_set("models")


def test_recognition_shares_apply_revisions_to_the_labels_on_arrival(tmp_path):
    from handflow.framework.files.labels import recognition_shares
    from handflow.framework.files.mcap_writer import McapWriter
    from handflow.framework.messages import Label, SegmentEvent

    def stamped(msg, stamp):
        msg.header.stamp_ns = stamp
        return msg

    path = tmp_path / "live.mcap"
    arrived = ["unknown"] * 3 + ["grasp"] * 7 + ["unknown"] * 10  # frames 0–9 grasp, 10–19 turn
    with McapWriter(path, flush_interval_s=None) as w:
        w.write("handflow/g/glove/performed", stamped(Label(label="grasp"), 0), 0)
        w.write("handflow/g/glove/performed", stamped(Label(label="turn"), 10), 10)
        for i, label in enumerate(arrived):
            w.write("handflow/g/seg/labels", stamped(Label(label=label, index=i), i), i)
        revision = SegmentEvent(kind="revision", label="grasp", start_index=1, end_index=2, previous_label="unknown")
        w.write("handflow/g/seg/events", stamped(revision, 12), 12)
    final = recognition_shares(path, "glove/performed", "seg/labels")
    assert final["grasp"] == {"frames": 10, "right": 0.9, "unknown": 0.1}
    assert final["turn"] == {"frames": 10, "right": 0.0, "unknown": 1.0}
    assert recognition_shares(path, "glove/performed", "seg/labels", revisions=False)["grasp"]["right"] == 0.7
