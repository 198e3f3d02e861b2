"""``handflow monitor [--graph NAME] [--connect EP] [--once [--json]] [--window S] [--foxglove [PORT]]``."""

from __future__ import annotations

import argparse
import json
import sys
import time

from ..observe.foxglove_bridge import BridgeError, start_bridge
from ..observe.monitor import WINDOW_S, Monitor, render
from ..runtime.discovery import add_auth_arguments
from ..runtime.param_service import LOCAL
from ._shared import add_foxglove_option, joined_graphs


def register(parser: argparse.ArgumentParser) -> None:
    """Live table of a running graph: topics, rates, latency, sequence gaps, last values, node health."""
    parser.add_argument(
        "--graph", help="name of the running graph (default: the only one running; with --connect: every graph there)"
    )
    parser.add_argument(
        "--connect", metavar="ENDPOINT", help="join this Zenoh endpoint (any hub of the graph) instead of a run-file"
    )
    add_auth_arguments(parser)
    parser.add_argument("--once", action="store_true", help="listen for --listen seconds, print one snapshot, exit")
    parser.add_argument("--json", action="store_true", help="with --once: print the snapshot as JSON")
    parser.add_argument("--listen", type=float, default=2.0, help="listening window of --once in seconds (default 2)")
    parser.add_argument("--window", type=float, default=WINDOW_S, help="sliding window for rates and latency (s)")
    parser.add_argument(
        "--wide",
        action="store_true",
        help="every column at full width (default: one line per topic within the terminal's width, COLUMNS when piped)",
    )
    add_foxglove_option(
        parser,
        "also stream every topic live to Foxglove on ws://127.0.0.1:PORT (default 8765)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.json and not args.once:
        print("error: --json needs --once (the live view is a table)", file=sys.stderr)
        return 2
    if (joined := joined_graphs(args)) is None:
        return 2
    session, found = joined
    graphs = sorted(found)
    graph = graphs[0] if len(graphs) == 1 else None
    bridge = None
    if args.foxglove is not None:
        try:
            who = args.cert_name if args.certs else LOCAL  # the graph's parameters, asked as this certificate
            bridge = start_bridge(session, graphs, "127.0.0.1", args.foxglove, params_as=who)
        except BridgeError as exc:
            session.close()
            print(f"error: {exc}", file=sys.stderr)
            return 2
        print(f"Foxglove live view on ws://127.0.0.1:{bridge.port}", file=sys.stderr)
    monitor = Monitor(session, graphs, window_s=max(args.window, args.listen) if args.once else args.window)
    title = f"handflow monitor — graph '{graph}'" if graph else f"handflow monitor — graphs {', '.join(graphs)}"
    try:
        if args.once:
            time.sleep(args.listen)
            snap = monitor.snapshot()
            if args.json:
                print(json.dumps(snap))
            else:
                from rich.console import Console

                console = Console()
                tables = render(snap, title, graph, None if args.wide else console.width)
                if args.wide:  # as wide as the tables: the terminal wraps what it cannot show
                    unlimited = console.options.update_width(1_000_000)
                    console = Console(width=console.measure(tables, options=unlimited).maximum)
                console.print(tables)
        else:
            _live(monitor, title, graph, args.wide)
    except KeyboardInterrupt:
        pass
    finally:
        monitor.close()
        if bridge is not None:
            bridge.close()
        session.close()
    return 0


def _live(monitor: Monitor, title: str, graph: str | None, wide: bool) -> None:
    from rich.live import Live

    with Live(refresh_per_second=4, screen=False) as live:
        while True:  # the terminal's width now: it may have been resized
            live.update(render(monitor.snapshot(), title, graph, None if wide else live.console.width))
            time.sleep(0.5)
