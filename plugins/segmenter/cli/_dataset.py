"""``handflow dataset REC.mcap… --topic NODE/PORT --out DATASET.npz``: labelled recordings → continuous recordings.

The labels come from a ``Label`` topic of each recording (``handflow collect``'s cues by default) or
from a CSV of intervals (``--labels``); see :mod:`..datasets._labelled_mcap` and docs/segmentation.md,
"From labelled recordings".
"""

from __future__ import annotations

import argparse
import sys

from handflow.framework.files.labels import LabelError
from handflow.framework.files.mcap_writer import RecordingError

from ..datasets import MIN_REPETITIONS, REST, build_dataset, label_stream, read_stream


def register_dataset(parser: argparse.ArgumentParser) -> None:
    """Turn labelled recordings into the continuous recordings evaluate segmentation and train-classes read."""
    parser.add_argument("recordings", nargs="+", metavar="REC.mcap", help="labelled MCAP recordings (sessions)")
    parser.add_argument("--topic", required=True, metavar="NODE/PORT", help="the stream to label, e.g. shadow/joints")
    parser.add_argument("--out", required=True, metavar="DATASET.npz", help="continuous .npz to write")
    parser.add_argument(
        "--labels", metavar="INTERVALS.csv", help="start_s,end_s,label rows (seconds from the stream's first message)"
    )
    parser.add_argument("--label-topic", metavar="NODE/PORT", help="the Label topic to read (default: the cue topic)")
    parser.add_argument("--joints", help="comma-separated joint names to keep, in this order (default: all)")
    parser.add_argument("--classes", help="the classes to expect (default: those the cues name, else every label)")
    parser.add_argument("--rounds", type=int, default=1, help="rounds per recording (a session is cut; default 1)")
    parser.set_defaults(func=run_dataset)


def run_dataset(args: argparse.Namespace) -> int:
    if args.labels and (len(args.recordings) != 1 or args.label_topic):
        print("error: --labels labels one recording; pass one REC.mcap and no --label-topic", file=sys.stderr)
        return 2
    if args.rounds < 1:
        print(f"error: --rounds must be >= 1, got {args.rounds}", file=sys.stderr)
        return 2
    joints = [j.strip() for j in args.joints.split(",")] if args.joints else None
    try:
        streams = []
        for path in args.recordings:
            stream, marks = read_stream(path, args.topic.strip("/"), joints)
            streams.append(label_stream(stream, marks, args.label_topic, args.labels))
        data = build_dataset(streams, args.classes.split(",") if args.classes else None, args.rounds)
        out = data.save(args.out)
    except (LabelError, RecordingError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {data.recordings} recording(s) to {out}")
    for c in data.frames:
        note = " (unknown: no model is trained for it)" if c == REST else ""
        print(f"{c}: {data.repetitions[c]} repetition(s), {data.frames[c]} frames{note}")
    few = [c for c in data.frames if c != REST and data.repetitions[c] < MIN_REPETITIONS]
    for c in few:
        print(
            f"warning: class {c} has only {data.repetitions[c]} repetition(s); record at least {MIN_REPETITIONS} "
            f"(`handflow collect … --append`)",
            file=sys.stderr,
        )
    if data.recordings < 3:
        print(
            f"warning: {data.recordings} recording(s); leave one recording out needs 3 or more (more rounds, or --rounds 1)",
            file=sys.stderr,
        )
    return 0
