"""``handflow echo TOPIC [--graph G] [-n N | --once] [--json]``: the decoded messages of one topic of a running
graph, as ``ros2 topic echo`` shows them (docs/monitoring.md, "One topic's messages")."""

from __future__ import annotations

import argparse
import json
import queue
import sys
import time
from typing import Any

import yaml

from .. import keys, wire
from ..messages import MessageError
from ..runtime.discovery import add_auth_arguments
from ..runtime.param_service import NODE_TIMEOUT_S
from ._shared import one_graph, param_asker

PORT_CHECK_S = 1.0  # nothing came within this: check that the node has such an output port


def register(parser: argparse.ArgumentParser) -> None:
    """Print the decoded messages of one topic of a running graph, as `ros2 topic echo` does."""
    parser.add_argument("topic", metavar="TOPIC", help="node/port (e.g. scale/out) or handflow/GRAPH/node/port")
    parser.add_argument("--graph", help="name of the running graph (default: the only one running)")
    parser.add_argument("-n", "--count", type=int, metavar="N", help="exit 0 after N messages (default: until Ctrl-C)")
    parser.add_argument("--once", action="store_true", help="exit 0 after the first message (-n 1)")
    parser.add_argument("--json", action="store_true", help="one JSON object a line (every field in full)")
    parser.add_argument(
        "--truncate",
        type=int,
        default=128,
        metavar="N",
        help="without --json: show at most N items of a list and N characters of a text (default 128; 0: all)",
    )
    parser.add_argument("--connect", metavar="ENDPOINT", help="join this Zenoh endpoint (any hub of the graph)")
    add_auth_arguments(parser)
    parser.epilog = "exit codes: 0 after N messages or Ctrl-C, 2 no such graph, node or port, or bad arguments"
    parser.set_defaults(func=run)


def parse_topic(text: str) -> tuple[str | None, str, str] | None:
    """(graph or None, node, port) of ``node/port``, ``handflow/GRAPH/node/port`` or its ROS 2 name; None if
    it is neither."""
    parts = text.strip("/").split("/")
    if len(parts) == 4 and parts[0] == keys.PREFIX and all(parts):
        return parts[1], parts[2], parts[3]
    if len(parts) == 2 and all(parts) and parts[0] != keys.PREFIX:
        return None, parts[0], parts[1]
    return None


def shown(message: dict[str, Any], truncate: int) -> str:
    """A message as ``ros2 topic echo`` prints it: YAML fields, long lists and texts cut at ``truncate``."""

    def cut(value: Any) -> Any:
        if isinstance(value, dict):
            return {k: cut(v) for k, v in value.items()}
        if isinstance(value, list):
            items = [cut(v) for v in (value[:truncate] if truncate else value)]
            return items + ["..."] if truncate and len(value) > truncate else items
        if isinstance(value, str) and truncate and len(value) > truncate:
            return value[:truncate] + "..."
        return value

    body = {k: v for k, v in message.items() if k != "type"}
    return yaml.safe_dump(cut(body), sort_keys=False, default_flow_style=False, width=1_000_000) + "---"


def _problem(args: argparse.Namespace) -> str | None:
    if parse_topic(args.topic) is None:
        return f"TOPIC {args.topic!r} is node/port (e.g. scale/out) or handflow/GRAPH/node/port"
    if args.count is not None and args.count < 1:
        return f"-n must be at least 1 (got {args.count})"
    if args.once and args.count not in (None, 1):
        return "--once is -n 1; give one of them"
    graph = parse_topic(args.topic)[0]
    if graph and args.graph and graph != args.graph:
        return f"TOPIC names graph '{graph}' but --graph says '{args.graph}'; give one of them"
    return None


def run(args: argparse.Namespace) -> int:
    if problem := _problem(args):
        print(f"error: {problem}", file=sys.stderr)
        return 2
    named, node, port = parse_topic(args.topic)
    args.graph = args.graph or named
    if (joined := one_graph(args)) is None:
        return 2
    session, graph, info = joined
    try:
        nodes = info.get("nodes", [])
        external = f"{node}/{port}" in info.get("external", [])  # fed from outside the graph (collect's cues)
        if not node.startswith("_") and node not in nodes and not external:
            print(f"error: graph '{graph}' has no node '{node}' (its nodes: {', '.join(nodes)})", file=sys.stderr)
            return 2
        received: queue.SimpleQueue = queue.SimpleQueue()
        sub = session.declare_subscriber(keys.topic_key(graph, node, port), received.put)
        try:
            return _echo(args, session, graph, node, port, received)
        except KeyboardInterrupt:
            return 0
        finally:
            sub.undeclare()
    finally:
        session.close()


def _echo(args, session, graph: str, node: str, port: str, received: queue.SimpleQueue) -> int:
    wanted = 1 if args.once else args.count
    printed, started, checked = 0, time.monotonic(), port.startswith("_") or node.startswith("_")
    while wanted is None or printed < wanted:
        try:
            sample = received.get(timeout=0.1)
        except queue.Empty:
            if not checked and time.monotonic() - started > PORT_CHECK_S:
                checked = True
                if missing := _no_such_port(session, graph, node, port, args):
                    print(f"error: {missing}", file=sys.stderr)
                    return 2
            continue
        try:
            message = wire.unpack(*wire.sample_parts(sample)).to_dict()
        except MessageError as exc:
            print(f"warning: a message on {node}/{port} does not decode: {exc}", file=sys.stderr)
            continue
        print(json.dumps(message) if args.json else shown(message, args.truncate), flush=True)
        printed += 1
    return 0


def _no_such_port(session, graph: str, node: str, port: str, args: argparse.Namespace) -> str | None:
    """What is wrong when ``node`` (an installed plugin's) has no output ``port``; None if it has, or if that
    cannot be told here (a plugin given by path, or not installed on this machine)."""
    from ..registry import PluginError, plugin_entries

    for answer in param_asker(session, graph, args)(node, {"op": "get"}, NODE_TIMEOUT_S + 3):
        entry = plugin_entries().get(answer.get("plugin", ""))
        if not answer.get("ok") or entry is None:
            continue
        try:
            cls = entry.load()
            ports = cls.output_types(cls.Params.model_validate(answer["params"]))
        except (PluginError, ValueError):
            return None
        if port not in ports:
            return (
                f"node '{node}' ({answer['plugin']}) has no output port '{port}'; its outputs: "
                f"{', '.join(f'{node}/{p}' for p in ports) or 'none'}"
            )
    return None
