"""The graph-level ``ros2:`` option: selected topics republished for ROS 2 as rmw_zenoh does it (docs/ros2.md).

Runs in the launcher on its hub session.  The payload of a handflow sample already is the CDR of
the topic's ROS 2 type, so it is forwarded unchanged; only the key, the attachment and the
liveliness tokens are rmw_zenoh's.  Samples of JSON-speaking peers (no attachment) are skipped.
"""

from __future__ import annotations

import logging

from .. import keys, wire
from ..graphs.model import Graph
from ..messages import MessageError
from ..ros2.rmw_zenoh import RosNode, RosPublisher
from ..ros2.types import ros_type, type_hash

log = logging.getLogger(__name__)


class Ros2Bridge:
    """Republishes a graph's ``ros2.publish`` topics of ``host`` under one ROS 2 node; :meth:`close` withdraws them."""

    def __init__(self, session, graph: Graph, host: str | None = None) -> None:
        settings = graph.spec.ros2
        assert settings is not None
        self.node = RosNode(session, settings.ros_node_name(graph.name), settings.domain_id, settings.namespace)
        self.publishers: dict[str, RosPublisher] = {}
        self._subs = []
        for source, topic in settings.topics().items():
            rn = graph.nodes.get(source.partition("/")[0])
            if (rn.spec.host if rn is not None else None) != host:
                continue  # the launcher of the host running the node publishes it
            cls = graph.source_type(source)
            assert cls is not None  # checked by graph validation
            ros = ros_type(cls.TYPE)
            pub = self.node.publisher(topic, ros, type_hash(ros), settings.depth)
            self.publishers[source] = pub
            node_id, _, port = source.partition("/")
            key = keys.topic_key(graph.name, node_id, port)
            self._subs.append(session.declare_subscriber(key, lambda sample, pub=pub: _forward(sample, pub)))
            log.info("ROS 2: %s → %s (%s) on %s", source, topic, ros, pub.key)

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        self.node.close()


def _forward(sample, pub: RosPublisher) -> None:
    payload, att = wire.sample_parts(sample)
    if att is None:
        return
    try:
        wire.parse_attachment(att)
    except MessageError:
        return
    pub.put(payload)
