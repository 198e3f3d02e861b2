"""``handflow compare A.mcap B.mcap [--topics GLOB ...] [--json]``: per topic, messages matched by stamp."""

from __future__ import annotations

import argparse
import json
import sys

from ..files.mcap_compare import TopicComparison, as_json, compare_recordings
from ..files.mcap_writer import RecordingError


def register(parser: argparse.ArgumentParser) -> None:
    """Compare two recordings: per topic (node/port), messages matched by stamp, equal / differing / only in one."""
    parser.add_argument("a", metavar="A.mcap", help="first recording (e.g. the live run)")
    parser.add_argument("b", metavar="B.mcap", help="second recording (e.g. its replay)")
    parser.add_argument(
        "--topics",
        nargs="+",
        metavar="GLOB",
        help="node/port globs as for record (default: every data topic, whose node and port names do not start "
        "with '_'; '_runtime/*' or '_params/*' compares those)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object (see docs/recording.md)")
    parser.epilog = "exit codes: 0 equal, 1 a difference, 2 a missing or unreadable file, or no topic to compare"
    parser.set_defaults(func=run)


def _table(result: list[TopicComparison]) -> str:
    width = max([len(c.topic) for c in result] + [5])
    lines = [
        f"{'topic':<{width}}  {'equal':>8} {'differing':>9} {'only in A':>9} {'only in B':>9}  first difference (stamp ns)"
    ]
    for c in result:
        first = "" if c.first_difference_ns is None else str(c.first_difference_ns)
        lines.append(f"{c.topic:<{width}}  {c.equal:>8} {c.differing:>9} {c.only_a:>9} {c.only_b:>9}  {first}")
    differ = [c.topic for c in result if not c.same]
    lines.append(f"different: {', '.join(differ)}" if differ else f"equal: {len(result)} topic(s)")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    try:
        result, report_a, report_b = compare_recordings(args.a, args.b, args.topics)
    except RecordingError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for report in (report_a, report_b):
        if report.recovered:
            print(f"warning: {report.describe()}; compared what was recovered", file=sys.stderr)
    if not result:
        globs = " ".join(args.topics or ["**"])
        print(f"error: no topic matching {globs} in {args.a} or {args.b}; check --topics", file=sys.stderr)
        return 2
    print(json.dumps(as_json(result, report_a, report_b)) if args.json else _table(result))
    return 0 if all(c.same for c in result) else 1
