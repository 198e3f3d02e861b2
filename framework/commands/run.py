"""``handflow run GRAPH.yaml [--duration S] [--record FILE.mcap] [--host NAME] [--watch]``."""

from __future__ import annotations

import argparse
import json
import sys

from ..runtime.startup import StartupProgress
from ..runtime.stop_signals import StopSignals
from ..runtime.zygote import Zygote, zygote_while
from ._shared import add_foxglove_option, add_set_option, graph_with_sets


def register(parser: argparse.ArgumentParser) -> None:
    """Run a graph: one process per node (or group), supervised, until Ctrl-C or --duration."""
    parser.add_argument("graph", help="YAML graph file, or the name of a shipped graph (e.g. demo)")
    parser.add_argument("--duration", type=float, help="stop after this many seconds (orderly, exit 0)")
    parser.add_argument(
        "--record", metavar="FILE.mcap", help="record the graph's 'record.topics' (default all) to MCAP"
    )
    parser.add_argument("--host", help="run only the nodes whose 'host' is NAME (a graph spread over machines)")
    add_set_option(parser)
    add_foxglove_option(
        parser,
        "live view: stream every topic to Foxglove on ws://127.0.0.1:PORT (default 8765)",
    )
    parser.add_argument(
        "--watch",
        action="store_true",
        help="restart a node when its plugin's source or its entry in the graph file changes; the others keep "
        "running (docs/tuning.md)",
    )
    parser.add_argument(
        "--summary-json", metavar="FILE", help="write per-process restarts, exit codes and failures as JSON"
    )
    parser.epilog = (
        "exit codes: 0 ok (a node that failed, restarted and runs at the end is noted in the summary), "
        "1 empty or failed recording, 2 bad graph, missing input (file, device, extra) or bad arguments, "
        "3 a node in a crash loop, 4 a node failed and was not running at the end, 130 Ctrl-C or SIGTERM before the "
        "graph was loaded (docs/reliability.md)"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # Ctrl-C and SIGTERM only ask to stop from here on: the start-up checks it and stops in order
    with StopSignals() as stop:
        return _run(args, stop)


def _run(args: argparse.Namespace, stop: StopSignals) -> int:
    progress = StartupProgress()
    progress.say("handflow run %s: importing its plugins, checking its inputs, starting its processes", args.graph)
    # imports the plugins for the node processes while the graph is checked here
    with zygote_while(args.graph) as zygote:
        return _run_with(args, stop, progress, zygote)


def _run_with(args: argparse.Namespace, stop: StopSignals, progress: StartupProgress, zygote: Zygote | None) -> int:
    # the rest of what a run needs, imported once the first line is out (docs/pipelines.md, "Start-up")
    from ..graphs.model import FoxgloveSettings, GraphError
    from ..graphs.overrides import OverrideError
    from ..network.sessions import EndpointInUse
    from ..observe.foxglove_bridge import BridgeError, start_bridge
    from ..runtime.launcher import run_graph
    from ..runtime.param_service import LOCAL
    from ..runtime.status import StatusLine

    try:
        if args.set and args.watch:
            raise OverrideError(
                "--set and --watch cannot be combined: an edit of the graph file would drop the values set"
            )
        graph, text = graph_with_sets(args.graph, args.set, args.host)
    except (GraphError, OverrideError) as exc:
        print(exc if isinstance(exc, GraphError) else f"error: {exc}", file=sys.stderr)
        if isinstance(exc, GraphError):
            print(f"{args.graph}: fix the problems above (see `handflow validate {args.graph}`)", file=sys.stderr)
        return 2
    if stop.is_set():  # before anything ran: nothing to stop, no recording begun
        print("interrupted", file=sys.stderr)
        return 130
    record_path = args.record or (graph.spec.record.path if graph.spec.record else None)
    recorder = bridge = None
    status = StatusLine(graph.name, graph.spec.status) if graph.spec.status else None
    fox = graph.spec.foxglove
    if args.foxglove is not None:
        fox = FoxgloveSettings(host=fox.host if fox else "127.0.0.1", port=args.foxglove)

    def attach(launcher):
        nonlocal recorder, bridge
        if status is not None:
            status.attach(launcher.session)
        if fox is not None:
            bridge = start_bridge(launcher.session, graph.name, fox.host, fox.port, params_as=LOCAL, spec=graph)
        if record_path:
            from ..recorder.graph_recorder import GraphRecorder

            recorder = GraphRecorder.for_graph(graph, record_path)  # outputs are relative to the current directory
            recorder.attach(launcher.session)

    progress.say("graph '%s' checked (%.1fs); starting its nodes", graph.name, progress.elapsed())
    try:
        launcher = run_graph(
            graph,
            args.duration,
            args.host,
            on_ready=attach,
            zygote=zygote,
            watch=args.watch,
            progress=progress,
            text=text,
            stop=stop,
        )
    except (ValueError, BridgeError, EndpointInUse) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    finally:
        if status is not None:
            status.close()
        if recorder is not None:
            recorder.close()
        if bridge is not None:
            bridge.close()
    if args.summary_json:
        with open(args.summary_json, "w") as f:
            json.dump(launcher.summary(), f, indent=2)
    launcher.close()
    failed, down = launcher.failure_report()
    if failed:
        print("failed nodes:\n" + "\n".join(f"  {line}" for line in failed), file=sys.stderr)
    if launcher.crash_loops:
        for why in launcher.crash_loops:
            print(f"error: crash loop: {why} (see 'failed nodes' above)", file=sys.stderr)
        return 3
    if down:
        print("error: a node failed and was not running at the end (see 'failed nodes' above)", file=sys.stderr)
        return 4
    if recorder is not None and recorder.writer.failure:
        print(f"error: {recorder.writer.failure}", file=sys.stderr)
        return 1
    if recorder is not None and recorder.writer.message_count == 0:
        print(
            f"warning: the recording {recorder.writer.path} holds no messages; check the graph's 'record.topics' "
            "and that its nodes publish (a longer --duration helps if start-up is slow)",
            file=sys.stderr,
        )
        return 1
    return 0
