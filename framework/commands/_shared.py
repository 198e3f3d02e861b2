"""Options and steps several commands share (docs/monitoring.md, docs/tuning.md)."""

from __future__ import annotations

import argparse
import sys

from ..runtime.discovery import DiscoveryError, join_graphs

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
