"""``handflow layout GRAPH [-o FILE]``: the flagship's Foxglove layout for a graph's topics (docs/foxglove.md)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..graphs.model import GraphError, load_graph
from ..observe.foxglove_layout import layout_for, unshown


def register(parser: argparse.ArgumentParser) -> None:
    """Write the flagship's Foxglove layout for a graph's topics (import it in Foxglove: Layouts → Import from file)."""
    parser.add_argument("graph", help="YAML graph file, or the name of a shipped graph (e.g. demo_segment_only)")
    parser.add_argument("-o", "--output", metavar="FILE.json", help="write the layout here (default: standard output)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    try:
        graph = load_graph(args.graph)
    except GraphError as exc:
        print(exc, file=sys.stderr)
        return 2
    text = layout_for(graph.name)
    if args.output:
        Path(args.output).write_text(text)
    else:
        sys.stdout.write(text)
    where = args.output or "standard output"
    print(f"{where}: the flagship layout for graph '{graph.name}' (/handflow/{graph.name}/…)", file=sys.stderr)
    if missing := unshown(graph):
        print(f"  panels of topics '{graph.name}' does not carry stay empty: {', '.join(missing)}", file=sys.stderr)
    return 0
