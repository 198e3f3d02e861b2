"""``handflow param list|get|set [--graph G] NODE[.KEY] [VALUE] [--restart]``, ``param dump [FILE]`` and
``param load FILE [--restart]``: a running graph's parameters (docs/tuning.md; files: :mod:`.param_files`)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import yaml

from ..runtime.discovery import add_auth_arguments
from ..runtime.param_service import NODE_TIMEOUT_S, RESTART_TIMEOUT_S
from . import param_files
from ._shared import one_graph, param_asker
from .param_files import show


def register(parser: argparse.ArgumentParser) -> None:
    """List, read or change a running graph's parameters (live, or with --restart); dump them to or load a file."""
    parser.add_argument(
        "action",
        choices=["list", "get", "set", "dump", "load"],
        help="list NODE's (or every node's) parameters; get; set; dump every node's to FILE (YAML, default "
        "stdout); load FILE: set the keys whose value differs",
    )
    parser.add_argument(
        "target", nargs="?", metavar="NODE[.KEY] | FILE", help="a node, or one of its parameters; with dump/load: FILE"
    )
    parser.add_argument(
        "value", nargs="?", metavar="VALUE", help="with set: the new value, a YAML scalar (3, 0.5, sine, null)"
    )
    parser.add_argument(
        "--restart",
        action="store_true",
        help="with set/load: restart the node when it takes KEY only at start (load: once per node)",
    )
    parser.add_argument("--graph", help="name of the running graph (default: the only one running)")
    parser.add_argument("--connect", metavar="ENDPOINT", help="join this Zenoh endpoint (the hub running the node)")
    add_auth_arguments(parser)
    parser.epilog = (
        "exit codes: 0 done, 1 the node refused the value (its message says why; the old value stays; load: any "
        "key), 2 no such graph, node or parameter, bad arguments, a malformed FILE, or no permission (docs/tuning.md)"
    )
    parser.set_defaults(func=run, late_positionals=("target", "value"))


def scalar(text: str) -> Any:
    """VALUE read as a YAML scalar (``3``, ``0.5``, ``null``, ``[1, 2]``); text that YAML reads as something
    JSON cannot carry (a date) or cannot read at all stays the text itself."""
    try:
        value = yaml.safe_load(text)
        json.dumps(value)
    except (yaml.YAMLError, TypeError, ValueError):
        return text
    return value


def _request(args: argparse.Namespace) -> tuple[str, str, dict[str, Any]] | str:
    """(node or ``*``, key, request), or what is wrong with the arguments."""
    if args.action in ("dump", "load"):
        if args.value is not None or (args.action == "load" and not args.target):
            return f"param {args.action} takes {'FILE' if args.action == 'load' else '[FILE]'} only"
        return "*", "", {"op": args.action}
    node, _, key = (args.target or "").partition(".")
    if args.action == "list":
        return node or "*", key, {"op": "get"}
    if not node:
        return f"param {args.action} needs NODE{'.KEY VALUE' if args.action == 'set' else '[.KEY]'}"
    if args.action == "get":
        return node, key, {"op": "get"}
    if not key or args.value is None:
        return "param set needs NODE.KEY VALUE, e.g. `handflow param set scale.gain 3`"
    return node, key, {"op": "set", "key": key, "value": scalar(args.value), "restart": args.restart}


def run(args: argparse.Namespace) -> int:
    asked = _request(args)
    if isinstance(asked, str):
        print(f"error: {asked}", file=sys.stderr)
        return 2
    node, key, request = asked
    if (joined := one_graph(args)) is None:
        return 2
    session, graph, info = joined
    try:
        ask = param_asker(session, graph, args)
        timeouts = NODE_TIMEOUT_S + 3, RESTART_TIMEOUT_S + 10
        if request["op"] == "dump":
            return param_files.dump(graph, info.get("nodes", []), ask, args.target, timeouts[0])
        if request["op"] == "load":
            return param_files.load(graph, info.get("nodes", []), ask, args.target, args.restart, timeouts)
        replies = ask(node, request, timeouts[1] if request.get("restart") else timeouts[0])
    finally:
        session.close()
    if not replies:
        nodes = ", ".join(info.get("nodes", []))
        print(f"error: no node '{node}' answered in graph '{graph}' (its nodes: {nodes})", file=sys.stderr)
        return 2
    return _print(sorted(replies, key=lambda r: r.get("node", "")), key, request)


def _print(replies: list[dict[str, Any]], key: str, request: dict[str, Any]) -> int:
    failed = [r for r in replies if not r.get("ok")]
    for r in failed:
        print(f"error: {r.get('error', 'refused')}", file=sys.stderr)
    if failed:
        return max(int(r.get("code", 1)) for r in failed)
    for r in replies:
        params, live = r["params"], set(r.get("live", []))
        if key and key not in params:
            print(f"error: node '{r['node']}' has no parameter '{key}' (it has: {', '.join(params)})", file=sys.stderr)
            return 2
        if key and request["op"] == "get":
            print(show(params[key]))
            continue
        for k in [key] if key else sorted(params):
            print(f"{r['node']}.{k} = {show(params[k])}{'  (live)' if k in live else ''}")
    return 0
