"""``handflow migrate OLD.mcap NEW.mcap``: a JSON-dialect recording rewritten as rosbag2 CDR MCAP (docs/recording.md)."""

from __future__ import annotations

import argparse
import sys

from ..files.mcap_reader import ReadReport, iter_recording
from ..files.mcap_writer import McapWriter, RecordingError
from ..messages import MessageError


def register(parser: argparse.ArgumentParser) -> None:
    """Rewrite a recording as rosbag2-compatible CDR MCAP, keeping times, sequence numbers, metadata and attachments."""
    parser.add_argument(
        "file", help="recording to convert (JSON dialect or already CDR; truncated files: what is recoverable)"
    )
    parser.add_argument("out", help="the new .mcap file (must differ from FILE)")
    parser.set_defaults(func=run)


def migrate(src: str, dst: str) -> ReadReport:
    """Convert ``src`` into ``dst``; returns the read report of ``src`` (messages, recovered or not)."""
    report = ReadReport(src)
    with McapWriter(dst, flush_interval_s=None) as w:
        for rm in iter_recording(src, report=report):
            msg = rm.decode()
            w.write(rm.topic, msg, rm.log_time_ns, rm.publish_time_ns)
        for name, data in report.metadata.items():
            w.add_metadata(name, data)
        for att in report.attachments.values():
            w.add_attachment(att.name, att.data, att.media_type)
    return report


def run(args: argparse.Namespace) -> int:
    if args.file == args.out:
        print("handflow migrate: OUT must be a new file, not the recording being read", file=sys.stderr)
        return 2
    try:
        report = migrate(args.file, args.out)
    except (RecordingError, MessageError) as exc:
        print(f"handflow migrate: {exc}", file=sys.stderr)
        return 1
    note = "" if report.complete else f" (source truncated: {report.error})"
    print(f"wrote {report.messages} message(s) to {args.out} as rosbag2 CDR MCAP{note}")
    return 0
