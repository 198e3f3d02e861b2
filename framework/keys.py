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


def report_key(graph: str) -> str:
    """The launcher asks the nodes for a heartbeat now, which also wakes their main loop (at shutdown)."""
    return f"{PREFIX}/{graph}/_report"


def events_key(graph: str) -> str:
    """Where the runtime publishes :class:`handflow.framework.messages.RuntimeEvent` messages."""
    return f"{PREFIX}/{graph}/_runtime/events"


def params_key(graph: str) -> str:
    """The graph's parameter topic: every accepted change as a ParamChange (docs/tuning.md)."""
    return f"{PREFIX}/{graph}/_params/changes"


def node_params_key(graph: str, node: str) -> str:
    """Where a node process answers its launcher's parameter requests (docs/tuning.md)."""
    return topic_key(graph, node, "_params")


def param_request_key(graph: str, who: str, node: str) -> str:
    """Where a launcher answers ``handflow param`` for ``node`` (``*``: every node); ``who`` is the
    asker's certificate name in a TLS graph (the hub's access control holds it to its own), else ``local``."""
    return f"{PREFIX}/{graph}/_params/{who}/{node}"


def ros_name(key: str) -> str:
    """The ROS 2 topic name of a Zenoh key: a leading ``/`` (recordings and the live view, docs/recording.md)."""
    return key if key.startswith("/") else "/" + key


def key_of_ros_name(name: str) -> str:
    """The Zenoh key of a recorded topic name, with or without the leading ``/`` (Zenoh keys cannot start with one)."""
    return name[1:] if name.startswith("/") else name


def split_key(key: str) -> tuple[str, str, str] | None:
    """``handflow/<graph>/<node>/<port>`` → (graph, node, port), else None."""
    parts = str(key).split("/")
    if len(parts) != 4 or parts[0] != PREFIX:
        return None
    return parts[1], parts[2], parts[3]
