"""``handflow replay FILE.mcap [--speed X] [--loop] [--topics GLOB ...] [--into G.yaml [--lockstep]] [--foxglove]``."""

from __future__ import annotations

import argparse
import logging
import sys
import threading
from pathlib import Path

from .. import keys
from ..files.mcap_reader import ReadReport, iter_recording
from ..files.mcap_writer import RecordingError
from ..graphs.model import Graph, GraphError, load_graph
from ..observe.foxglove_bridge import BridgeError, start_bridge
from ..recorder.graph_recorder import GraphRecorder
from ..recorder.param_replay import RecordedChanges, read_changes
from ..recorder.replay import (
    GraphWatcher,
    LockstepReplayer,
    ReplayError,
    ReplayPlan,
    ReplayStats,
    TimedReplayer,
    external_inputs,
)
from ..runtime.discovery import DiscoveryError, add_auth_arguments, join
from ..runtime.launcher import Launcher
from ..runtime.stop_signals import StopSignals
from ..runtime.zygote import Zygote, zygote_while
from ._shared import add_foxglove_option, add_set_option, graph_with_sets

log = logging.getLogger("handflow.replay")

DRAIN_TIMEOUT_S = 5.0


def register(parser: argparse.ArgumentParser) -> None:
    """Publish a recording with its original timing, into a running graph or one it launches (--into)."""
    parser.add_argument("file", help="MCAP recording")
    parser.add_argument("--speed", type=float, default=1.0, help="time scale: 2 = twice as fast (default 1)")
    parser.add_argument("--loop", action="store_true", help="start over at the end until Ctrl-C")
    parser.add_argument("--topics", nargs="+", metavar="GLOB", help="globs over the recorded node/port topics")
    parser.add_argument(
        "--into",
        metavar="GRAPH.yaml",
        help="launch this graph and feed it the recorded topics its nodes read but do not publish",
    )
    add_set_option(parser)
    parser.add_argument(
        "--lockstep",
        action="store_true",
        help="with --into: virtual time, each message fully processed before the next (deterministic)",
    )
    parser.add_argument(
        "--no-param-changes",
        action="store_true",
        help="with --lockstep: do not apply the parameter changes the recording holds (docs/tuning.md)",
    )
    parser.add_argument(
        "--record",
        metavar="FILE.mcap",
        help="with --into: record the launched graph's topics (and the replayed inputs) to MCAP",
    )
    add_foxglove_option(
        parser,
        "serve the replay to Foxglove on ws://127.0.0.1:PORT (default 8765), driven from its playback bar: "
        "play, pause, seek, speed (with --lockstep: a seek back restarts the graph's nodes and catches up); "
        "runs until Ctrl-C",
    )
    parser.add_argument("--graph", help="replay into this running graph (default: the recording's graph, if running)")
    parser.add_argument("--connect", metavar="ENDPOINT", help="join this Zenoh endpoint instead of a run-file")
    add_auth_arguments(parser)
    parser.add_argument("--ready-timeout", type=float, default=30.0, help="seconds to wait for the graph's nodes")
    parser.add_argument(
        "--step-timeout", type=float, default=10.0, help="lock-step: seconds one message may take to settle"
    )
    parser.set_defaults(func=run)


def _recorded_graph(path: str) -> str | None:
    """The recorded graph's name (metadata, else the first topic's key)."""
    report = ReadReport(Path(path))
    for rm in iter_recording(path, report=report):
        meta = report.metadata.get("handflow.graph", {})
        if meta.get("name"):
            return meta["name"]
        parts = keys.split_key(rm.topic)
        return parts[0] if parts else None
    return report.metadata.get("handflow.graph", {}).get("name")


def _check_args(args: argparse.Namespace) -> str | None:
    if not args.speed > 0:
        return f"--speed must be > 0 (got {args.speed}); use 2 for twice as fast, 0.5 for half speed"
    if args.record and not args.into:
        return "--record needs --into GRAPH.yaml (to record a running graph use `handflow record`)"
    if getattr(args, "set", None) and not args.into:
        return "--set needs --into GRAPH: it sets a parameter of a node the replay launches"
    if args.lockstep and not args.into:
        return (
            "--lockstep needs --into GRAPH.yaml: the replayer launches the graph in lock-step mode to know its wiring"
        )
    if args.foxglove is not None and args.loop:
        return "--foxglove replays until Ctrl-C (seek back from Foxglove's playback bar); leave out --loop"
    if args.lockstep and args.loop:
        return "--lockstep cannot --loop (a lock-step replay is a finite, deterministic run)"
    if not Path(args.file).is_file():
        return f"recording {args.file} not found; pass an .mcap file"
    return None


def run(args: argparse.Namespace) -> int:
    """Ctrl-C and SIGTERM ask to stop (:class:`..runtime.stop_signals.StopSignals`, from the first line on):
    before the graph is joined or launched the command exits 130 (``interrupted``); after, the replay stops
    at its next message, the launched graph stops in order, what was replayed is printed and it exits 0
    (docs/reliability.md)."""
    with StopSignals() as signals:
        return _run(args, signals.event)


def _run(args: argparse.Namespace, stop: threading.Event) -> int:
    problem = _check_args(args)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    try:
        recorded = _recorded_graph(args.file)
        if args.into:
            return _replay_into(args, recorded, stop)
        return _replay_join(args, recorded, stop)
    except (RecordingError, DiscoveryError, BridgeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except ReplayError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1


def _interrupted() -> int:
    print("interrupted", file=sys.stderr)
    return 130


def _print_stats(stats: ReplayStats, where: str, stopped: bool = False) -> None:
    if stats.report is not None and stats.report.recovered:
        print(f"warning: {stats.report.describe()}", file=sys.stderr)
    print(
        f"replayed {stats.total} message(s) on {len(stats.published)} topic(s) into {where}"
        + (f" ({stats.loops} loops)" if stats.loops > 1 else "")
        + (" before it was stopped (Ctrl-C or SIGTERM)" if stopped else "")
    )


def _replay_join(args: argparse.Namespace, recorded: str | None, stop: threading.Event) -> int:
    """Publish into an already running graph (found by name, or at --connect)."""
    target = args.graph or recorded
    session, info = join(
        None if args.connect else target, args.connect, args.certs, args.cert_name, args.credentials, args.user
    )
    try:
        if stop.is_set():  # before anything was published
            return _interrupted()
        graph = None
        if info is not None and Path(info.graph_file).is_file():
            try:
                graph = load_graph(info.graph_file)
            except GraphError:
                graph = None
        target = info.graph if info is not None else target
        watcher = GraphWatcher(session, target)
        if graph is not None:  # heartbeats prove the routes to its nodes exist
            watcher.wait_alive(graph.nodes, args.ready_timeout, stop=stop)
        elif not watcher.wait_for(lambda: bool(watcher.health), min(args.ready_timeout, 3.0)) and args.certs:
            raise ReplayError(
                f"no heartbeat of graph '{target}' reached this machine over {args.connect}: is it running, and "
                f"does its 'zenoh.tls' grant certificate '{args.cert_name}' the recorded topics under 'publishers' "
                f"(docs/security.md)?"
            )
        plan = ReplayPlan(Path(args.file), args.topics, target)
        bridge, replayer = _timed(args, session, plan, target, stop)
        try:
            stats = replayer.run()
        finally:
            if bridge is not None:
                bridge.close()
        watcher.close()
    finally:
        session.close()
    _print_stats(stats, f"graph '{target}'", stop.is_set())
    return 0


def _replay_into(args: argparse.Namespace, recorded: str | None, stop: threading.Event) -> int:
    """Launch ``--into`` (lock-step or not), feed it, let it drain, stop it."""
    # the zygote imports the plugins for the node processes while the graph is loaded here (as `handflow run`)
    with zygote_while(args.into) as zygote:
        return _launch_into(args, recorded, stop, zygote)


def _launch_into(args: argparse.Namespace, recorded: str | None, stop: threading.Event, zygote: Zygote | None) -> int:
    try:
        graph, text = graph_with_sets(args.into, getattr(args, "set", None) or [])
    except GraphError as exc:
        print(f"{exc}\n{args.into}: fix the graph file (see `handflow validate {args.into}`)", file=sys.stderr)
        return 2
    except ValueError as exc:  # a --set that cannot be applied
        print(f"error: {exc}", file=sys.stderr)
        return 2
    sources = external_inputs(graph)
    if not sources:
        print(
            f"error: graph '{graph.name}' has no inputs fed from outside; declare the recorded topics its nodes "
            f"should read under 'external:' (e.g. glove/frames: GloveFrame) and point the inputs at them",
            file=sys.stderr,
        )
        return 2
    plan = ReplayPlan(Path(args.file), args.topics, graph.name, sources)
    if stop.is_set():  # nothing launched yet
        return _interrupted()
    launcher = Launcher(
        graph,
        lockstep=args.lockstep,
        log_level=logging.getLevelName(logging.getLogger().level),
        zygote=zygote,
        graph_text=text,
    )
    recorder = None
    result: dict[str, object] = {}
    bridge = None
    try:  # whatever fails from here on, the launcher is stopped and closed (its session too)
        if args.record:
            recorder = GraphRecorder.for_graph(graph, args.record)
            recorder.attach(launcher.session)
        launcher.start()
        watcher = GraphWatcher(launcher.session, graph.name)
        poll = launcher.poll
        watcher.wait_alive(graph.nodes, args.ready_timeout, poll, stop)
        if args.lockstep:
            replayer = LockstepReplayer(
                launcher.session, graph, graph.nodes, watcher, step_timeout_s=args.step_timeout, stop=stop, poll=poll
            )
            changes = None if args.no_param_changes else _recorded_changes(args.file, recorded, launcher, graph)
            if args.foxglove is None:
                work = lambda: replayer.run(plan, changes)  # noqa: E731
            else:
                from ..recorder.playback import ControlledLockstep

                bridge, playback = _serve_playback(args, launcher.session, plan, graph.name)
                restart = lambda: _in_supervisor(launcher, launcher.reset)  # noqa: E731
                work = ControlledLockstep(
                    replayer, plan, playback, stop, bridge.server, restart, changes, args.ready_timeout
                ).run
        else:
            bridge, replayer = _timed(args, launcher.session, plan, graph.name, stop)
            work = replayer.run
            if not stop.is_set():
                replayer.pubs.prepare(
                    [keys.topic_key(graph.name, *s.split("/", 1)) for s in sources], args.ready_timeout
                )
        thread = threading.Thread(target=_capture, args=(work, result), name="replay", daemon=True)
        thread.start()
        while thread.is_alive():  # supervise the graph while the replay runs
            launcher.poll()
            thread.join(0.05)
        if "error" in result:
            raise result["error"]  # type: ignore[misc]
        stats: ReplayStats = result["stats"]  # type: ignore[assignment]
        stopped = stop.is_set()  # by a signal (the block below sets it to end the replay on any path)
        if not args.lockstep and not stopped:
            _drain(graph, watcher, stats, launcher.poll)
        watcher.close()
    finally:
        stop.set()
        launcher.stop()
        if recorder is not None:
            recorder.close()
        if bridge is not None:
            bridge.close()
        launcher.close()
    _print_stats(stats, f"graph '{graph.name}'" + (" (lock-step)" if args.lockstep else ""), stopped)
    if stats.total == 0 and not stopped:
        print(
            f"warning: nothing replayed; the recording (graph '{recorded}') has none of the topics "
            f"{', '.join(sorted(sources))} that graph '{graph.name}' reads from outside",
            file=sys.stderr,
        )
    return 0


def _recorded_changes(path: str, recorded: str | None, launcher: Launcher, graph: Graph) -> RecordedChanges | None:
    """The recording's parameter changes, to apply in lock-step (docs/tuning.md); restarts are reported."""
    live, restarts = read_changes(path, recorded) if recorded else ([], [])
    for change in restarts:
        log.warning(
            "not applied: %s.%s = %s was set with a restart (a replay restarts no node)",
            change.node,
            change.key,
            change.value,
        )
    if live:
        log.info("applying %d recorded parameter change(s) at their stamps", len(live))
    return RecordedChanges(launcher.session, graph, live) if live else None


def _timed(args: argparse.Namespace, session, plan: ReplayPlan, graph: str, stop: threading.Event):
    """(Foxglove bridge or None, replayer): a timed replay, driven from Foxglove's playback bar with
    ``--foxglove`` (:mod:`..recorder.playback`)."""
    if args.foxglove is None:
        return None, TimedReplayer(session, plan, speed=args.speed, loop=args.loop, stop=stop)
    from ..recorder.playback import ControlledReplayer

    bridge, playback = _serve_playback(args, session, plan, graph)
    return bridge, ControlledReplayer(session, plan, playback, stop, bridge.server)


def _serve_playback(args: argparse.Namespace, session, plan: ReplayPlan, graph: str):
    """(Foxglove bridge, :class:`..recorder.playback.Playback`): the replay serves Foxglove itself, with the
    PlaybackControl capability (a graph started by ``--into`` opens no server of its own)."""
    from ..recorder.playback import SDK_MISSING, Playback, time_range

    if SDK_MISSING:  # without the extra, or an SDK without PlaybackControl
        raise BridgeError(
            f"replay --foxglove needs foxglove-sdk 0.30 or newer ({SDK_MISSING}): pip install -U 'handflow[foxglove]'"
        )
    playback = Playback(*time_range(plan.path), speed=args.speed)
    bridge = start_bridge(session, graph, "127.0.0.1", args.foxglove, playback=playback)
    print(f"Foxglove playback on ws://127.0.0.1:{bridge.port} (Ctrl-C to stop)", file=sys.stderr)
    return bridge, playback


def _in_supervisor(launcher: Launcher, call) -> None:
    """Run ``call()`` in the thread supervising ``launcher`` (at its next poll) and return once it ran, raising
    what it raised (e.g. :meth:`Launcher.reset`, which must not race the supervision's restarts)."""
    result: dict[str, BaseException] = {}
    done = threading.Event()

    def run() -> None:
        try:
            call()
        except BaseException as exc:
            result["error"] = exc
        finally:
            done.set()

    launcher.call_soon(run)
    done.wait()
    if "error" in result:
        raise result["error"]


def _capture(work, result: dict[str, object]) -> None:
    try:
        result["stats"] = work()
    except Exception as exc:
        result["error"] = exc


def _drain(graph: Graph, watcher: GraphWatcher, stats: ReplayStats, poll) -> None:
    """Timed replay: wait (bounded) until the heartbeats show every replayed message handled downstream."""
    sent = {f"{p[1]}/{p[2]}": n for k, n in stats.published.items() if (p := keys.split_key(k))}

    def drained() -> bool:
        for nid, rn in graph.nodes.items():
            counters = watcher.health.get(nid, {})
            for port, src in rn.spec.inputs.items():
                node, _, out = src.partition("/")
                published = (
                    sent.get(src, 0)
                    if node not in graph.nodes
                    else watcher.health.get(node, {}).get(f"published.{out}", 0)
                )
                if counters.get(f"handled.{port}", 0) < published:
                    return False
        return True

    with watcher.cond:
        seen = dict(watcher.beats)
    fresh = lambda: all(watcher.beats[n] >= seen.get(n, 0) + 2 for n in graph.nodes)  # noqa: E731 - counters newer than the replay
    if not watcher.wait_for(lambda: fresh() and drained(), DRAIN_TIMEOUT_S, poll):
        log.warning(
            "the graph had not handled every replayed message %.0fs after the replay; stopping it anyway",
            DRAIN_TIMEOUT_S,
        )
