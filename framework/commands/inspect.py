"""``handflow inspect FILE.mcap [--json]``: topics, types, counts, time range, rates; recovers truncated files."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from ..files.labels import summarize_intervals, topic_intervals
from ..files.mcap_reader import ReadReport, iter_recording
from ..files.mcap_writer import RecordingError
from ..messages import Label


def register(parser: argparse.ArgumentParser) -> None:
    """Summarise a recording: topics, message types, counts, time range, rates, labels (works on truncated files)."""
    parser.add_argument("file", help="MCAP recording")
    parser.add_argument("--json", action="store_true", help="print one JSON object (see docs/recording.md)")
    parser.set_defaults(func=run)


def _rate(count: int, first_ns: int, last_ns: int) -> float:
    return (count - 1) / ((last_ns - first_ns) / 1e9) if count > 1 and last_ns > first_ns else 0.0


def summarize(path: str) -> dict[str, Any]:
    """The ``--json`` object: totals, per-topic type/count/rate, recovered flag, metadata, attachments.

    A topic's rate is over its publish times (the stamps), so a node that published a backlog in a
    burst after a slow start shows its steady rate; over receive times only where the stamps do not
    advance (docs/recording.md, "Inspecting").
    """
    report = ReadReport(path)
    stats: dict[str, list[int]] = {}  # topic → [count, first log, last log, first publish, last publish] (ns)
    marks: dict[str, list[tuple[int, str]]] = {}  # Label topic → (stamp, label) as received
    for rm in iter_recording(path, report=report):
        if rm.type_name == Label.TYPE:
            msg = rm.decode()
            marks.setdefault(rm.topic, []).append((msg.header.stamp_ns, msg.label))
        s = stats.get(rm.topic)
        if s is None:
            stats[rm.topic] = [1, rm.log_time_ns, rm.log_time_ns, rm.publish_time_ns, rm.publish_time_ns]
        else:
            s[0] += 1
            s[1], s[2] = min(s[1], rm.log_time_ns), max(s[2], rm.log_time_ns)
            s[3], s[4] = min(s[3], rm.publish_time_ns), max(s[4], rm.publish_time_ns)
    topics = []
    for topic in sorted(stats):
        count, first, last, first_pub, last_pub = stats[topic]
        rate = _rate(count, first_pub, last_pub) or _rate(count, first, last)
        topics.append(
            {
                "topic": topic,
                "type": report.channels[topic]["type"],
                "count": count,
                "rate_hz": round(rate, 3),
                "start_ns": first,
                "end_ns": last,
            }
        )
    end_pub = max((s[4] for s in stats.values()), default=0)
    return {
        "file": str(path),
        "total_messages": report.messages,
        "start_ns": min((t["start_ns"] for t in topics), default=None),
        "end_ns": max((t["end_ns"] for t in topics), default=None),
        "topics": topics,
        "recovered": report.recovered,
        "recovered_messages": report.messages if report.recovered else None,
        "error": report.error or None,
        "views": sorted(t for t, c in report.channels.items() if "view_of" in c),
        "metadata": report.metadata,
        "attachments": sorted(report.attachments),
        "labels": {t: summarize_intervals(topic_intervals(m, end_pub)) for t, m in sorted(marks.items())},
    }


def _text(summary: dict[str, Any]) -> str:
    lines = [f"file:       {summary['file']}"]
    if summary["recovered"]:
        lines.append(
            f"RECOVERED:  truncated or damaged file ({summary['error']}); "
            f"{summary['total_messages']} message(s) recovered from its complete chunks"
        )
    start, end = summary["start_ns"], summary["end_ns"]
    duration = (end - start) / 1e9 if start is not None else 0.0
    lines.append(f"messages:   {summary['total_messages']} over {duration:.3f} s")
    graph = summary["metadata"].get("handflow.graph", {})
    if graph:
        lines.append(f"graph:      {graph.get('name')} ({graph.get('file')})")
    if summary["attachments"]:
        lines.append(f"attached:   {', '.join(summary['attachments'])}")
    width = max([len(t["topic"]) for t in summary["topics"]] + [5])
    lines.append(f"{'topic':<{width}}  {'type':<22} {'count':>8} {'rate Hz':>9}")
    for t in summary["topics"]:
        lines.append(f"{t['topic']:<{width}}  {t['type']:<22} {t['count']:>8} {t['rate_hz']:>9.2f}")
    for v in summary["views"]:
        lines.append(f"{v:<{width}}  (Foxglove image view)")
    for topic, per_label in summary["labels"].items():
        shown = ", ".join(f"{k} ×{v['intervals']} ({v['seconds']:.1f} s)" for k, v in per_label.items())
        lines.append(f"labels on {topic}: {shown or 'none'}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    try:
        summary = summarize(args.file)
    except RecordingError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(summary) if args.json else _text(summary))
    return 0
