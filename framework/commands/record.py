"""``handflow record [GRAPH] --out FILE.mcap [--topics GLOB ...] [--duration S] [--connect EP]``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..files.mcap_writer import McapWriter, RecordingError
from ..graphs.model import GraphError, load_graph
from ..recorder.graph_recorder import GraphRecorder
from ..runtime.discovery import DiscoveryError, add_auth_arguments, join_graphs
from ..runtime.stop_signals import StopSignals


def register(parser: argparse.ArgumentParser) -> None:
    """Record a running graph's topics to MCAP from outside (until Ctrl-C or --duration)."""
    parser.add_argument(
        "graph", nargs="?", help="name of a running graph, or its YAML file (default: the only graph reachable)"
    )
    parser.add_argument("--out", required=True, metavar="FILE.mcap", help="recording to write")
    parser.add_argument(
        "--topics",
        nargs="+",
        metavar="GLOB",
        help="globs over node/port (default: the graph's record.topics, else all data topics)",
    )
    parser.add_argument("--duration", type=float, help="stop after this many seconds")
    parser.add_argument(
        "--connect", metavar="ENDPOINT", help="join this Zenoh endpoint instead of finding the graph's run-file"
    )
    add_auth_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    with StopSignals() as stop:  # Ctrl-C and SIGTERM ask to stop: every path below closes the session
        return _record(args, stop)


def _record(args: argparse.Namespace, stop: StopSignals) -> int:
    graph = None
    name = args.graph
    if name and (name.endswith((".yaml", ".yml")) or Path(name).is_file()):
        try:
            graph = load_graph(args.graph)
        except GraphError as exc:
            print(f"{exc}\n{args.graph}: fix the graph file, or pass the running graph's name", file=sys.stderr)
            return 2
        name = graph.name
    try:
        session, info, found = join_graphs(name, args.connect, args.certs, args.cert_name, args.credentials, args.user)
    except DiscoveryError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    try:
        return _record_from(args, session, graph, info, found, stop)
    finally:
        session.close()


def _record_from(args: argparse.Namespace, session, graph, info, found, stop: StopSignals) -> int:
    if len(found) > 1:
        print(f"error: several graphs run there ({', '.join(sorted(found))}); name the one to record", file=sys.stderr)
        return 2
    if stop.is_set():
        print("interrupted", file=sys.stderr)
        return 130
    name = next(iter(found))
    if graph is None and info is not None and Path(info.graph_file).is_file():
        try:
            graph = load_graph(info.graph_file)
        except GraphError:
            graph = None  # recorded without provenance; the topics are what matters
    try:
        if graph is not None:
            recorder = GraphRecorder.for_graph(graph, args.out, args.topics)
        else:
            writer = McapWriter(args.out)
            writer.add_metadata("handflow.graph", {"name": name})
            recorder = GraphRecorder(writer, name, args.topics)
    except RecordingError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    recorder.attach(session)
    print(f"recording graph '{name}' to {args.out} (Ctrl-C to stop)", file=sys.stderr)
    try:
        stop.wait(args.duration)
    finally:
        recorder.close(log_summary=False)  # printed once, below
    print(recorder.summary)
    return 0
