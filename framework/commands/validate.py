"""``handflow validate GRAPH.yaml``."""

from __future__ import annotations

import argparse
import sys

from ..graphs.model import validate_file


def register(parser: argparse.ArgumentParser) -> None:
    """Check a graph file and the inputs its nodes read; print every problem as file:line: what to change (exit 0 valid, 2 invalid)."""
    parser.add_argument("graph", help="YAML graph file")
    parser.add_argument(
        "--host",
        metavar="NAME",
        help="check the files, devices and extras of the nodes whose 'host' is NAME (default: the nodes without one)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    graph, problems = validate_file(args.graph, preflight=True, host=args.host)
    for p in problems:
        print(f"{args.graph}:{p.line}: {p.message}", file=sys.stderr)
    if problems:
        print(f"{args.graph}: {len(problems)} problem(s)", file=sys.stderr)
        return 2
    print(f"{args.graph}: valid graph '{graph.name}' with {len(graph.nodes)} node(s)")
    return 0
