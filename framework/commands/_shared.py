"""Options and steps several commands share (docs/monitoring.md, docs/tuning.md)."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from typing import Any

from ..keys import param_request_key
from ..runtime.discovery import DiscoveryError, join_graphs
from ..runtime.param_service import LOCAL

FOXGLOVE_PORT = 8765  # Foxglove's default WebSocket port


def add_foxglove_option(parser: argparse.ArgumentParser, help: str) -> None:
    """``--foxglove [PORT]`` (default :data:`FOXGLOVE_PORT` when given without a port)."""
    parser.add_argument("--foxglove", nargs="?", const=FOXGLOVE_PORT, type=int, metavar="PORT", help=help)


def joined_graphs(args: argparse.Namespace) -> tuple | None:
    """The Zenoh session and the graphs found with ``--graph``, ``--connect`` and the authentication
    options; None after printing why not (the command exits 2)."""
    try:
        session, _, found = join_graphs(
            args.graph, args.connect, args.certs, args.cert_name, args.credentials, args.user
        )
    except DiscoveryError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return None
    return session, found


def one_graph(args: argparse.Namespace) -> tuple[Any, str, dict] | None:
    """The Zenoh session, name and hub info of the one graph :func:`joined_graphs` finds (``param``, ``echo``);
    None after printing why not (none, or several without ``--graph``: the command exits 2)."""
    if (joined := joined_graphs(args)) is None:
        return None
    session, found = joined
    if len(found) > 1:
        session.close()
        print(f"error: several graphs run there ({', '.join(sorted(found))}); name one with --graph", file=sys.stderr)
        return None
    graph, info = next(iter(found.items()))
    return session, graph, info


def param_asker(session: Any, graph: str, args: argparse.Namespace) -> Callable[[str, dict, float], list[dict]]:
    """``ask(node, request, timeout)``: the replies of ``graph``'s parameter service for ``node`` (``*``: every
    node), asked as the authentication options say (docs/tuning.md, "How it works")."""
    who = args.cert_name if args.certs else LOCAL

    def ask(node: str, request: dict[str, Any], timeout: float) -> list[dict[str, Any]]:
        answers = session.get(param_request_key(graph, who, node), payload=json.dumps(request), timeout=timeout)
        return [json.loads(r.ok.payload.to_bytes()) for r in answers if r.ok is not None]

    return ask
