"""Topic keys: ``handflow/<graph>/<node>/<port>`` and the runtime's own keys (docs/architecture.md).

Pure string functions shared by the network, the runtime and the MCAP files; they import no Zenoh.
"""

from __future__ import annotations

PREFIX = "handflow"


def topic_key(graph: str, node: str, port: str) -> str:
    return f"{PREFIX}/{graph}/{node}/{port}"


def clock_key(graph: str) -> str:
    return f"{PREFIX}/{graph}/_clock"


def start_key(graph: str) -> str:
    """The launcher's start signal: nodes tick only once every node of the graph has reported ready."""
    return f"{PREFIX}/{graph}/_start"


def events_key(graph: str) -> str:
    """Where the runtime publishes :class:`handflow.framework.messages.RuntimeEvent` messages."""
    return f"{PREFIX}/{graph}/_runtime/events"


def split_key(key: str) -> tuple[str, str, str] | None:
    """``handflow/<graph>/<node>/<port>`` → (graph, node, port), else None."""
    parts = str(key).split("/")
    if len(parts) != 4 or parts[0] != PREFIX:
        return None
    return parts[1], parts[2], parts[3]
