"""``ros2.subscribe`` / ``ros2.publish``: a ROS 2 topic into a graph and a graph topic out to ROS 2 (docs/ros2.md).

Each node opens its own Zenoh session to the ROS 2 system (by default rmw_zenoh's router on
``tcp/localhost:7447``), declares a ROS 2 node with rmw_zenoh's liveliness tokens and exchanges
CDR samples with rmw_zenoh's keys and attachments.  Received samples are queued by the Zenoh
thread and published by ``tick()`` (``rate_hz``), so node hooks never run concurrently.
"""

from __future__ import annotations

import json
import queue
from typing import Literal

import zenoh
from pydantic import BaseModel, Field, field_validator

from handflow.framework.files.inputs import InputFile
from handflow.framework.files.params import StrictModel
from handflow.framework.messages import Array, Message, MessageError
from handflow.framework.plugin import Node
from handflow.framework.ros2.rmw_zenoh import DEFAULT_DEPTH, RosNode, check_name
from handflow.framework.ros2.type_hash import full_name

from .codec import RosCodec, native_type

QUEUE_SIZE = 10_000
LOG_EVERY = 100  # a stream of bad samples is logged once per this many


class Ros2Params(StrictModel):
    topic: str = Field(description="fully qualified ROS 2 topic name, e.g. /joint_states")
    type: str = Field(description="ROS 2 message type, e.g. sensor_msgs/msg/JointState")
    msg_files: list[InputFile] = Field(
        default_factory=list, description=".msg files (<package>/msg/<Name>.msg) of types not in the Jazzy store"
    )
    domain_id: int = Field(0, ge=0, le=232, description="ROS_DOMAIN_ID")
    node_name: str | None = Field(None, description="ROS 2 node name; default: the node id ('-' → '_')")
    namespace: str = "/"
    connect: list[str] = Field(
        default_factory=lambda: ["tcp/localhost:7447"], description="Zenoh endpoints of the ROS 2 system (its router)"
    )
    mode: Literal["peer", "client"] = "peer"
    depth: int = Field(DEFAULT_DEPTH, ge=1, description="history depth announced in the QoS")

    @field_validator("topic")
    @classmethod
    def _topic(cls, v: str) -> str:
        return check_name(v)

    @field_validator("type")
    @classmethod
    def _type(cls, v: str) -> str:
        if v.count("/") not in (1, 2) or not all(v.split("/")):
            raise ValueError(f"a ROS 2 type reads <package>/msg/<Name>, got {v!r}")
        return full_name(v)


class SubscribeParams(Ros2Params):
    rate_hz: float = Field(500.0, gt=0, description="how often queued samples are published into the graph")


def graph_type(ros_type: str) -> type[Message]:
    """The handflow message a ROS 2 type is carried as in a graph (docs/ros2.md)."""
    return native_type(ros_type) or Array


def _open(node: Node, p: Ros2Params) -> tuple[zenoh.Session, RosNode, RosCodec]:
    codec = RosCodec(p.type, [node.ctx.resolve_path(f) for f in p.msg_files])
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(p.mode))
    conf.insert_json5("connect/endpoints", json.dumps(p.connect))
    conf.insert_json5("connect/timeout_ms", "-1")  # keep trying while the ROS 2 side is not up yet
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)
    ros_node = RosNode(session, p.node_name or node.ctx.node_id.replace("-", "_"), p.domain_id, p.namespace)
    return session, ros_node, codec


class Ros2Subscribe(Node):
    """Bring a ROS 2 topic into the graph on 'out' (its handflow type, else an Array of its numeric fields)."""

    Params = SubscribeParams
    outputs = {"out": Message}

    @classmethod
    def output_types(cls, params: BaseModel) -> dict[str, type[Message]]:
        return {"out": graph_type(params.type)}

    def setup(self) -> None:
        self.session, self.ros_node, self.codec = _open(self, self.params)
        self.inbox: queue.Queue[tuple[bytes, int, int]] = queue.Queue(QUEUE_SIZE)
        self.rejected = 0
        self.source = f"ros2:{self.params.topic}"
        self.ros_node.subscriber(
            self.params.topic,
            self.codec.ros_type,
            self.codec.type_hash,
            self._on_sample,
            self.params.depth,
            self._reject,
        )

    def _on_sample(self, cdr: bytes, seq: int, stamp_ns: int) -> None:
        try:
            self.inbox.put_nowait((cdr, seq, stamp_ns))
        except queue.Full:
            self._reject(f"queue of {QUEUE_SIZE} samples full; raise rate_hz")

    def _reject(self, reason: str) -> None:
        self.rejected += 1
        if self.rejected % LOG_EVERY == 1:
            self.ctx.log.warning("%s: dropped a sample (%d so far): %s", self.params.topic, self.rejected, reason)

    def tick(self) -> None:
        while True:
            try:
                cdr, seq, stamp_ns = self.inbox.get_nowait()
            except queue.Empty:
                return
            try:
                msg = self.codec.decode(cdr, self.source, seq, stamp_ns)
            except MessageError as exc:
                self._reject(str(exc))
                continue
            self.ctx.publish("out", msg, stamp_ns=msg.header.stamp_ns)

    def teardown(self) -> None:
        if hasattr(self, "session"):
            self.ros_node.close()
            self.session.close()


class Ros2Publish(Node):
    """Publish the messages arriving on 'in' as a ROS 2 topic (handflow counterpart type, or an Array by field names)."""

    Params = Ros2Params
    inputs = {"in": Message}

    @classmethod
    def input_types(cls, params: BaseModel) -> dict[str, type[Message]]:
        return {"in": graph_type(params.type)}

    def setup(self) -> None:
        self.session, self.ros_node, self.codec = _open(self, self.params)
        self.publisher = self.ros_node.publisher(
            self.params.topic, self.codec.ros_type, self.codec.type_hash, self.params.depth
        )

    def on_message(self, port: str, msg: Message) -> None:
        self.publisher.put(self.codec.encode(msg))

    def teardown(self) -> None:
        if hasattr(self, "session"):
            self.ros_node.close()
            self.session.close()
