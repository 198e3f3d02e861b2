"""Foxglove's Topic Graph panel: the ``ConnectionGraph`` capability of the live view (docs/foxglove.md).

The graph file says which node publishes which topic and which nodes read it, on every host, so the
launcher's live view shows the whole graph of a multi-machine run (nodes of another host as
``<host>/<node>``); topics are named as in the live view and in recordings
(``/handflow/<graph>/<node>/<port>``).  A topic fed from outside the graph (``external:``) has
subscribers and no publisher.
"""

from __future__ import annotations

from collections import defaultdict
from typing import TYPE_CHECKING

from ..keys import ros_name, topic_key

if TYPE_CHECKING:
    from foxglove.websocket import ConnectionGraph

    from ..graphs.model import Graph


def connection_graph(graph: Graph) -> ConnectionGraph:
    """Publishers and subscribers of every data topic of ``graph``."""
    from foxglove.websocket import ConnectionGraph  # the optional extra, checked by the bridge

    def who(nid: str) -> str:
        host = graph.nodes[nid].spec.host
        return f"{host}/{nid}" if host else nid

    published: dict[str, set[str]] = defaultdict(set)
    subscribed: dict[str, set[str]] = defaultdict(set)
    for nid, rn in graph.nodes.items():
        for port in rn.cls.output_types(rn.params):
            published[ros_name(topic_key(graph.name, nid, port))].add(who(nid))
        for source in rn.spec.inputs.values():
            node, _, port = source.partition("/")
            subscribed[ros_name(topic_key(graph.name, node, port))].add(who(nid))
    result = ConnectionGraph()
    for topic, ids in published.items():
        result.set_published_topic(topic, sorted(ids))
    for topic, ids in subscribed.items():
        result.set_subscribed_topic(topic, sorted(ids))
    return result
