"""``handflow collect GRAPH --topic NODE/PORT --classes a,b,c --reps N``: cued collection (docs/recording.md, "Cued collection").

Runs the graph, shows a cue per repetition in the terminal (the class, a countdown, rest between;
the order shuffled per round with the seed, :mod:`..recorder.cues`) and records the stream with
the cue topic, ``Label`` messages the graph's nodes may read (``external: {cue/labels: Label}``),
in one MCAP.  Ctrl-C keeps every finished repetition; ``--append`` adds rounds to a session.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
from pathlib import Path

from .. import keys, wire
from ..files.mcap_reader import ReadReport, iter_recording
from ..files.mcap_writer import McapWriter, RecordingError
from ..graphs.model import Graph, GraphError, load_graph
from ..observe.foxglove_bridge import BridgeError, start_bridge
from ..recorder.cues import REST, check_classes, cue_message, recorded_cues, schedule
from ..recorder.graph_recorder import GraphRecorder
from ..runtime.launcher import Launcher
from ..runtime.param_service import LOCAL
from ..runtime.runner import START_WAIT_S
from ..runtime.zygote import Zygote, zygote_while
from ._shared import add_foxglove_option

CUE_TOPIC = "cue/labels"


def register(parser: argparse.ArgumentParser) -> None:
    """Cued collection: run a graph, cue each repetition of each class, record the stream and the cues."""
    parser.add_argument("graph", help="YAML graph file, or the name of a shipped graph (e.g. collect_gestures)")
    parser.add_argument("--topic", required=True, metavar="NODE/PORT", help="the stream to label, e.g. shadow/joints")
    parser.add_argument("--classes", required=True, help="comma-separated class names, e.g. grasp,pinch,wave")
    parser.add_argument("--reps", type=int, required=True, help="repetitions of every class (rounds)")
    parser.add_argument("--seed", type=int, default=0, help="shuffles the order within each round (default 0)")
    parser.add_argument("--cue-s", type=float, default=4.0, help="seconds to perform each cued class (default 4)")
    parser.add_argument("--rest-s", type=float, default=2.0, help="seconds of rest after each repetition (default 2)")
    parser.add_argument("--lead-s", type=float, default=2.0, help="seconds to get ready before the first cue")
    parser.add_argument("--out", default="out/session.mcap", metavar="FILE.mcap", help="default out/session.mcap")
    parser.add_argument("--append", action="store_true", help="add rounds to the session already in --out")
    parser.add_argument(
        "--cue-topic", default=CUE_TOPIC, metavar="NODE/PORT", help=f"where the cues go (default {CUE_TOPIC})"
    )
    add_foxglove_option(parser, "live view of the stream and the cues in Foxglove on ws://127.0.0.1:PORT")
    parser.epilog = (
        "exit codes: 0 done (also after Ctrl-C: finished repetitions are kept), 1 recording failed, 2 bad input"
    )
    parser.set_defaults(func=run)


def _check_topics(graph: Graph, topic: str, cue_topic: str) -> str | None:
    """What is wrong with ``--topic`` / ``--cue-topic`` for ``graph``, or None."""
    outputs = sorted(f"{nid}/{port}" for nid, rn in graph.nodes.items() for port in rn.cls.output_types(rn.params))
    if topic not in outputs:
        return f"--topic {topic}: graph '{graph.name}' publishes no such topic; it publishes {', '.join(outputs)}"
    if cue_topic.partition("/")[0] in graph.nodes or "/" not in cue_topic.strip("/"):
        return (
            f"--cue-topic {cue_topic}: name a NODE/PORT that no node of graph '{graph.name}' uses (default {CUE_TOPIC})"
        )
    declared = graph.spec.external.get(cue_topic)
    if declared is not None and declared.rpartition(".")[2] != "Label":
        return f"--cue-topic {cue_topic}: graph '{graph.name}' declares it as {declared}; cues are Label messages"
    return None


def _check_args(args: argparse.Namespace) -> tuple[list[str], int] | str:
    """(classes, first round) or what to change."""
    try:
        classes = check_classes(args.classes.split(","))
    except ValueError as exc:
        return str(exc)
    if args.reps < 1 or args.cue_s <= 0 or args.rest_s <= 0 or args.lead_s < 0:
        return "--reps must be >= 1, --cue-s and --rest-s > 0 seconds, --lead-s >= 0"
    out = Path(args.out)
    if not args.append:
        if out.exists():
            return f"{out} exists; pass --append to add rounds to that session, or another --out"
        return classes, 0
    if not out.is_file():
        return f"--append: {out} does not exist; record the session first (without --append)"
    try:
        recorded, _, next_round = recorded_cues(out, _cue_key(args))
    except RecordingError as exc:
        return f"--append: {exc}"
    if recorded and recorded != classes:
        return f"--append: {out} was cued with --classes {','.join(recorded)}; use the same classes"
    if not recorded:
        return f"--append: {out} holds no cues on {args.cue_topic}; append to a session of `handflow collect`"
    return classes, next_round


def _cue_key(args: argparse.Namespace) -> str:
    return keys.topic_key(args.graph_name, *args.cue_topic.strip("/").split("/", 1))


class Cuer:
    """Publishes the cues of a session and shows them in the terminal; Ctrl-C sets ``stop``."""

    def __init__(self, launcher: Launcher, graph: Graph, cue_topic: str, classes: list[str]) -> None:
        self.launcher = launcher
        self.classes = classes
        self.pub = launcher.session.declare_publisher(keys.topic_key(graph.name, *cue_topic.split("/", 1)))
        self.stop = threading.Event()
        self.seq = 0
        self.finished: dict[str, int] = dict.fromkeys(classes, 0)
        self.tty = sys.stderr.isatty()

    def publish(self, label: str, index: int, stamp_ns: int | None = None) -> int:
        stamp = time.time_ns() if stamp_ns is None else stamp_ns
        msg = cue_message(label, index, self.classes, stamp)
        msg.header.source, msg.header.seq = "cue", self.seq
        self.seq += 1
        payload, att = wire.pack(msg)
        self.pub.put(payload, attachment=att)
        return stamp

    def wait(self, seconds: float, what: str = "") -> bool:
        """Supervise the graph for ``seconds`` (a countdown on a terminal); False once Ctrl-C was pressed."""
        end = time.monotonic() + seconds
        shown = None
        while (left := end - time.monotonic()) > 0:
            if self.stop.is_set():
                return False
            self.launcher.poll()
            if self.tty and what and (n := int(left) + 1) != shown:
                shown = n
                print(f"\r{what}  {n:>2} s ", end="", file=sys.stderr, flush=True)
            time.sleep(min(0.05, left))
        if self.tty and what:
            print(f"\r{what}  done", file=sys.stderr, flush=True)
        return not self.stop.is_set()

    def run(self, args: argparse.Namespace, first_round: int) -> None:
        say = lambda text: print(text, file=sys.stderr, flush=True)  # noqa: E731
        say(
            f"get ready: {args.reps} round(s) of {', '.join(self.classes)}; {args.cue_s:g} s each, {args.rest_s:g} s rest"
        )
        self.publish(REST, -1)
        if not self.wait(args.lead_s, "starting in"):
            return self._end(None)
        n = len(self.classes)
        for cue in schedule(self.classes, args.reps, args.seed, first_round):
            k = cue.index % n + 1
            start = self.publish(cue.label, cue.index)
            if not self.tty:
                say(
                    f"round {cue.round - first_round + 1}/{args.reps} · {k}/{n}: perform {cue.label.upper()} now ({args.cue_s:g} s)"
                )
            else:
                say(f"round {cue.round - first_round + 1}/{args.reps} · {k}/{n}:")
            if not self.wait(args.cue_s, f"  perform {cue.label.upper()} now"):
                return self._end(start)
            self.publish(REST, cue.index)
            self.finished[cue.label] += 1
            if not self.tty:
                say(f"  rest ({args.rest_s:g} s)")
            if not self.wait(args.rest_s, "  rest"):
                return self._end(None)
        self._end(None)

    def _end(self, interrupted_at: int | None) -> None:
        """The last cue: ``""`` (nothing cued from now on); an interrupted repetition is withdrawn at its stamp."""
        if interrupted_at is not None:
            self.publish("", -1, interrupted_at)
        self.publish("", -1)
        time.sleep(0.3)  # the recorder receives the last cue and the frames before it


def run(args: argparse.Namespace) -> int:
    # the zygote imports the plugins for the node processes while the graph is checked here (as `handflow run`)
    with zygote_while(args.graph) as zygote:
        return _run(args, zygote)


def _run(args: argparse.Namespace, zygote: Zygote | None) -> int:
    try:
        graph = load_graph(args.graph, preflight=True)
    except GraphError as exc:
        print(exc, file=sys.stderr)
        print(f"{args.graph}: fix the problems above (see `handflow validate {args.graph}`)", file=sys.stderr)
        return 2
    args.graph_name = graph.name
    problem = _check_topics(graph, args.topic.strip("/"), args.cue_topic.strip("/"))
    checked = problem or _check_args(args)
    if isinstance(checked, str):
        print(f"error: {checked}", file=sys.stderr)
        return 2
    classes, first_round = checked
    out = Path(args.out)
    target = out.with_name(out.stem + ".part.mcap") if args.append else out
    topics = None
    if graph.spec.record and graph.spec.record.topics:
        topics = [*graph.spec.record.topics, args.topic, args.cue_topic]
    try:
        recorder = GraphRecorder.for_graph(graph, target, topics)
    except RecordingError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    bridge = None
    try:
        launcher = Launcher(graph, zygote=zygote)
    except ValueError as exc:
        recorder.close(log_summary=False)
        print(f"error: {exc}", file=sys.stderr)
        return 2
    cuer = Cuer(launcher, graph, args.cue_topic, classes)
    old = {s: signal.signal(s, lambda *_: cuer.stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        recorder.attach(launcher.session)
        if args.foxglove is not None:
            bridge = start_bridge(launcher.session, graph.name, "127.0.0.1", args.foxglove, params_as=LOCAL, spec=graph)
        launcher.start()
        if _wait_ready(launcher, cuer.stop):
            cuer.run(args, first_round)
    except BridgeError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    finally:
        launcher.stop()
        for s, h in old.items():
            signal.signal(s, h)
        recorder.close(log_summary=False)
        if bridge is not None:
            bridge.close()
        launcher.close()
    if recorder.writer.failure:
        print(f"error: {recorder.writer.failure}", file=sys.stderr)
        return 1
    if args.append:
        try:
            append_recording(out, target)
        except RecordingError as exc:
            print(f"error: {exc}; the new rounds are kept in {target}", file=sys.stderr)
            return 1
    done = sum(cuer.finished.values())
    per_class = ", ".join(f"{c} {k}" for c, k in cuer.finished.items())
    stopped = " (stopped by Ctrl-C; finished repetitions kept)" if cuer.stop.is_set() else ""
    print(f"recorded {done} repetition(s) ({per_class}) to {out}{' (appended)' if args.append else ''}{stopped}")
    return 0


def _wait_ready(launcher: Launcher, stop: threading.Event) -> bool:
    """Supervise until every node is ready (or ``START_WAIT_S`` passed), then let them run; False on Ctrl-C."""
    t0 = time.monotonic()
    while not stop.is_set():
        launcher.poll()
        if launcher.all_ready() or launcher.settled() or time.monotonic() - t0 > START_WAIT_S:
            launcher.signal_start()
            return True
        time.sleep(0.05)
    return False


def append_recording(base: Path, part: Path) -> None:
    """Replace ``base`` by ``base`` followed by ``part`` (messages, metadata, attachments of both; ``part`` is
    removed once written).  Nothing is lost on a failure: both files stay as they were."""
    merged = base.with_name(base.stem + ".merging.mcap")
    reports = [ReadReport(base), ReadReport(part)]
    with McapWriter(merged, flush_interval_s=None) as w:
        for path, report in zip((base, part), reports):
            for rm in iter_recording(path, report=report):
                if rm.encoding == w.encoding:
                    w.write_encoded(rm.topic, rm.type_name, rm.data, rm.log_time_ns, rm.publish_time_ns, rm.sequence)
                else:
                    w.write(rm.topic, rm.decode(), rm.log_time_ns, rm.publish_time_ns)
        for name, data in reports[0].metadata.items():
            w.add_metadata(name, data)
        for report in reports:
            for name, att in report.attachments.items():
                if report is reports[0] or name not in reports[0].attachments:
                    w.add_attachment(name, att.data, att.media_type)
    if w.failure:
        raise RecordingError(w.failure)
    os.replace(merged, base)
    part.unlink()
