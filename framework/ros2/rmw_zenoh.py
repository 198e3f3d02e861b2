"""ROS 2 over Zenoh as rmw_zenoh (Jazzy) speaks it: key expressions, attachments, liveliness tokens (docs/ros2.md).

A ROS 2 topic ``/chatter`` of ``std_msgs/msg/String`` in domain 0 is the Zenoh key
``0/chatter/std_msgs::msg::dds_::String_/RIHS01_<hash>``; every sample carries the CDR message
and a 33-byte attachment (zenoh-ext serialisation of ``int64`` sequence number, ``int64`` source
timestamp in ns, and the 16-byte publisher GID as a length-prefixed sequence).  Nodes, publishers
and subscriptions announce themselves with liveliness tokens
``@ros2_lv/<domain>/<zid>/<nid>/<id>/<NN|MP|MS>/<enclave>/<namespace>/<node>[/<topic>/<type>/<hash>/<qos>]``
with ``/`` in names replaced by ``%``; that is what ``ros2 topic list`` and ``ros2 node list`` read.
"""

from __future__ import annotations

import hashlib
import itertools
import re
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass

from ..messages import MessageError

ADMIN_SPACE = "@ros2_lv"
GID_SIZE = 16
DEFAULT_DEPTH = 10  # the history depth of rclcpp/rclpy's default QoS profile
_ATTACHMENT = struct.Struct("<qqB16s")
# rmw_zenoh for Jazzy up to 0.2.3 named each field: (str, int64, str, int64, str, bytes), zenoh-ext serialised
_KEYED_ATTACHMENT = struct.Struct("<B15sqB16sqB10sB16s")
_KEYS = (b"sequence_number", b"source_timestamp", b"source_gid")
_NAME = re.compile(r"^(/[A-Za-z_][A-Za-z0-9_]*)+$")
_ENTITY_IDS = itertools.count()  # unique within the process; the session id makes them unique overall


def check_name(name: str, what: str = "topic") -> str:
    """A fully qualified ROS 2 name (``/a/b``): :class:`MessageError` saying what to change otherwise."""
    if not _NAME.match(name):
        raise MessageError(
            f"ROS 2 {what} name {name!r} is not valid: it must start with '/' and its parts may hold letters, "
            "digits and '_' only (not starting with a digit), e.g. '/hand/joint_states'"
        )
    return name


def dds_type(ros_type: str) -> str:
    """``std_msgs/msg/String`` → ``std_msgs::msg::dds_::String_`` (the type chunk of keys and tokens)."""
    pkg, sub, name = ros_type.split("/")
    return f"{pkg}::{sub}::dds_::{name}_"


def data_key(domain_id: int, topic: str, ros_type: str, type_hash: str) -> str:
    """The Zenoh key a topic's samples travel on."""
    return f"{domain_id}/{check_name(topic).strip('/')}/{dds_type(ros_type)}/{type_hash}"


def mangle(name: str) -> str:
    return name.replace("/", "%")


def qos_chunk(depth: int = DEFAULT_DEPTH, best_effort: bool = False) -> str:
    """The QoS part of a token: empty components are rmw_zenoh's defaults (reliable, volatile, keep-last)."""
    return f"{'2' if best_effort else ''}::,{depth}:,:,:,,"


def node_token(domain_id: int, zid: str, nid: int, node: str, namespace: str = "/") -> str:
    return f"{ADMIN_SPACE}/{domain_id}/{zid}/{nid}/{nid}/NN/%/{mangle(namespace)}/{node}"


def endpoint_token(
    kind: str,
    domain_id: int,
    zid: str,
    nid: int,
    eid: int,
    node: str,
    topic: str,
    ros_type: str,
    type_hash: str,
    qos: str,
    namespace: str = "/",
) -> str:
    """Liveliness token of a publisher (``kind="MP"``) or subscription (``"MS"``)."""
    head = f"{ADMIN_SPACE}/{domain_id}/{zid}/{nid}/{eid}/{kind}/%/{mangle(namespace)}/{node}"
    return f"{head}/{mangle(check_name(topic))}/{dds_type(ros_type)}/{type_hash}/{qos}"


def ros_type_of(dds: str) -> str:
    """``std_msgs::msg::dds_::String_`` → ``std_msgs/msg/String`` (inverse of :func:`dds_type`)."""
    parts = dds.split("::")
    if len(parts) != 4 or parts[2] != "dds_" or not parts[3].endswith("_"):
        raise MessageError(f"not an rmw_zenoh type name: {dds[:80]!r}")
    return f"{parts[0]}/{parts[1]}/{parts[3][:-1]}"


@dataclass(frozen=True)
class Entity:
    """What a liveliness token announces: a node (``NN``), publisher (``MP``), subscription (``MS``), …"""

    kind: str
    domain_id: int
    zid: str
    node: str
    namespace: str
    topic: str = ""
    ros_type: str = ""
    type_hash: str = ""


def parse_token(key: str) -> Entity:
    """The entity of an rmw_zenoh liveliness token; :class:`MessageError` for other keys."""
    parts = str(key).split("/")
    if len(parts) < 9 or parts[0] != ADMIN_SPACE or not parts[1].isdigit():
        raise MessageError(f"not an rmw_zenoh liveliness token: {str(key)[:120]!r}")
    kind, namespace = parts[5], parts[7].replace("%", "/")
    if kind == "NN":
        return Entity(kind, int(parts[1]), parts[2], parts[8], namespace)
    if len(parts) < 13:
        raise MessageError(f"rmw_zenoh {kind} token without topic, type, hash and QoS: {str(key)[:120]!r}")
    topic = parts[9].replace("%", "/")
    return Entity(kind, int(parts[1]), parts[2], parts[8], namespace, topic, ros_type_of(parts[10]), parts[11])


def gid_of(token: str) -> bytes:
    """A publisher's 16-byte GID, derived from its (unique) liveliness token."""
    return hashlib.sha256(token.encode()).digest()[:GID_SIZE]


def pack_attachment(seq: int, source_timestamp_ns: int, gid: bytes) -> bytes:
    return _ATTACHMENT.pack(seq, source_timestamp_ns, GID_SIZE, gid)


def parse_attachment(att: bytes | None) -> tuple[int, int, bytes]:
    """``(sequence number, source timestamp ns, GID)``; :class:`MessageError` for anything else.

    Reads the positional layout of rmw_zenoh ≥ 0.2.4 (Jazzy) and the earlier keyed one.
    """
    if att is not None and len(att) == _KEYED_ATTACHMENT.size:
        n1, k1, seq, n2, k2, stamp, n3, k3, n4, gid = _KEYED_ATTACHMENT.unpack(att)
        if (n1, k1, n2, k2, n3, k3, n4) == (15, _KEYS[0], 16, _KEYS[1], 10, _KEYS[2], GID_SIZE):
            return seq, stamp, gid
    if att is None or len(att) != _ATTACHMENT.size:
        raise MessageError(f"not an rmw_zenoh attachment: {None if att is None else len(att)} bytes, not 33")
    seq, stamp, n, gid = _ATTACHMENT.unpack(att)
    if n != GID_SIZE:
        raise MessageError(f"not an rmw_zenoh attachment: GID of {n} bytes, not {GID_SIZE}")
    return seq, stamp, gid


def split_data_key(key: str) -> tuple[int, str, str, str]:
    """``(domain, /topic, dds type, type hash)`` of a data key."""
    parts = str(key).split("/")
    if len(parts) < 4 or not parts[0].isdigit():
        raise MessageError(f"not an rmw_zenoh data key: {str(key)[:120]!r}")
    return int(parts[0]), "/" + "/".join(parts[1:-2]), parts[-2], parts[-1]


class RosNode:
    """A ROS 2 node on a Zenoh session: its liveliness token, and publishers and subscriptions under it."""

    def __init__(self, session, name: str, domain_id: int = 0, namespace: str = "/") -> None:
        if not re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", name):
            raise MessageError(f"ROS 2 node name {name!r} may hold letters, digits and '_' only")
        if namespace != "/":
            check_name(namespace, "namespace")
        self.session, self.name, self.domain_id, self.namespace = session, name, domain_id, namespace
        self.zid = str(session.zid())
        self.nid = next(_ENTITY_IDS)
        self.token_key = node_token(domain_id, self.zid, self.nid, name, namespace)
        self._token = session.liveliness().declare_token(self.token_key)
        self._children: list[RosPublisher | RosSubscriber] = []

    def _endpoint_token(self, kind: str, topic: str, ros_type: str, type_hash: str, qos: str) -> str:
        eid = next(_ENTITY_IDS)
        return endpoint_token(
            kind, self.domain_id, self.zid, self.nid, eid, self.name, topic, ros_type, type_hash, qos, self.namespace
        )

    def publisher(self, topic: str, ros_type: str, type_hash: str, depth: int = DEFAULT_DEPTH) -> RosPublisher:
        pub = RosPublisher(self, topic, ros_type, type_hash, depth)
        self._children.append(pub)
        return pub

    def subscriber(
        self,
        topic: str,
        ros_type: str,
        type_hash: str,
        callback: Callable[[bytes, int, int], None],
        depth: int = DEFAULT_DEPTH,
        on_error: Callable[[str], None] | None = None,
    ) -> RosSubscriber:
        sub = RosSubscriber(self, topic, ros_type, type_hash, callback, depth, on_error)
        self._children.append(sub)
        return sub

    def close(self) -> None:
        for child in self._children:
            child.close()
        self._children.clear()
        self._token.undeclare()


class RosPublisher:
    """Publishes CDR messages on a ROS 2 topic with rmw_zenoh's key, attachment and liveliness token."""

    def __init__(self, node: RosNode, topic: str, ros_type: str, type_hash: str, depth: int) -> None:
        self.key = data_key(node.domain_id, topic, ros_type, type_hash)
        self.token_key = node._endpoint_token("MP", topic, ros_type, type_hash, qos_chunk(depth))
        self.gid = gid_of(self.token_key)
        self.seq = 0
        self._token = node.session.liveliness().declare_token(self.token_key)
        self._pub = node.session.declare_publisher(self.key)

    def put(self, cdr: bytes) -> None:
        self.seq += 1  # rmw_zenoh's sequence numbers start at 1
        self._pub.put(cdr, attachment=pack_attachment(self.seq, time.time_ns(), self.gid))

    def close(self) -> None:
        self._pub.undeclare()
        self._token.undeclare()


class RosSubscriber:
    """Receives a ROS 2 topic: ``callback(cdr, seq, source_timestamp_ns)`` per sample of the expected type.

    It listens on every type hash of the topic's type so that a publisher with another definition
    is reported (``on_error``) instead of silently unmatched; samples without an rmw_zenoh attachment
    are reported too.
    """

    def __init__(
        self,
        node: RosNode,
        topic: str,
        ros_type: str,
        type_hash: str,
        callback: Callable[[bytes, int, int], None],
        depth: int,
        on_error: Callable[[str], None] | None,
    ) -> None:
        self.type_hash = type_hash
        self.key = data_key(node.domain_id, topic, ros_type, type_hash)
        self.token_key = node._endpoint_token("MS", topic, ros_type, type_hash, qos_chunk(depth))
        self._callback, self._on_error = callback, on_error or (lambda reason: None)
        self._token = node.session.liveliness().declare_token(self.token_key)
        self._sub = node.session.declare_subscriber(self.key.rpartition("/")[0] + "/*", self._on_sample)

    def _on_sample(self, sample) -> None:
        key_hash = str(sample.key_expr).rpartition("/")[2]
        if key_hash != self.type_hash:
            self._on_error(f"publisher of another definition ({key_hash}, expected {self.type_hash})")
            return
        att = sample.attachment
        try:
            seq, stamp, _ = parse_attachment(None if att is None else att.to_bytes())
        except MessageError as exc:
            self._on_error(str(exc))
            return
        self._callback(sample.payload.to_bytes(), seq, stamp)

    def close(self) -> None:
        self._sub.undeclare()
        self._token.undeclare()
