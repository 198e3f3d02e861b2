"""handflow messages as ROS 2 (Jazzy) messages in CDR (docs/ros2.md).

Standard types where they exist, handflow's own ``handflow_msgs/msg/*`` (the ``.msg`` files next to
this module) for the rest:

===========================  ==========================================================
handflow type                ROS 2 type
===========================  ==========================================================
JointState                   ``sensor_msgs/msg/JointState`` (``frame_id`` = ``<hand>/<handedness>``)
Image                        ``sensor_msgs/msg/Image``
Status                       ``diagnostic_msgs/msg/DiagnosticArray`` (one status: ``name`` = state,
                             ``message`` = text, counters as key/value pairs)
Array, GloveFrame, Contacts, ``handflow_msgs/msg/<same name>``
Points2D, LatentState,
Label, SegmentEvent,
RuntimeEvent
===========================  ==========================================================

:func:`encode_cdr` / :func:`decode_cdr` convert; the header's source node and sequence number are
not part of the body (they travel in the Zenoh attachment and MCAP's sequence field), so
:func:`decode_cdr` takes them as arguments.  :func:`schema_text` gives the ``ros2msg`` schema of a
type as rosbag2 writes it (the definition followed by its dependencies).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from importlib import resources
from typing import Any

import numpy as np

from ..messages import Header, Image, JointState, Message, MessageError, Status, message_types
from .cdr import CdrReader, CdrWriter, parse_msg
from .type_hash import rihs01

OWN_PACKAGE = "handflow_msgs"
# Standard ROS 2 Jazzy definitions used by the mapping (checked against rosbags' Jazzy store in tests).
STANDARD_MSGS = {
    "builtin_interfaces/msg/Time": "int32 sec\nuint32 nanosec",
    "std_msgs/msg/Header": "builtin_interfaces/Time stamp\nstring frame_id",
    "sensor_msgs/msg/JointState": "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort",
    "sensor_msgs/msg/Image": (
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data"
    ),
    "diagnostic_msgs/msg/KeyValue": "string key\nstring value",
    "diagnostic_msgs/msg/DiagnosticStatus": (
        "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\nstring name\nstring message\nstring hardware_id\ndiagnostic_msgs/KeyValue[] values"
    ),
    "diagnostic_msgs/msg/DiagnosticArray": "std_msgs/Header header\ndiagnostic_msgs/DiagnosticStatus[] status",
}
STANDARD_TYPES = {
    JointState.TYPE: "sensor_msgs/msg/JointState",
    Image.TYPE: "sensor_msgs/msg/Image",
    Status.TYPE: "diagnostic_msgs/msg/DiagnosticArray",
}
DIAGNOSTIC_LEVELS = {"ok": 0, "connected": 0, "warn": 1, "warning": 1, "error": 2, "failed": 2, "stale": 3}


@functools.cache
def own_msgs() -> dict[str, str]:
    """``handflow_msgs/msg/<Name>`` → ``.msg`` text of the definitions shipped with the package."""
    folder = resources.files(__package__) / "msg"
    return {f"{OWN_PACKAGE}/msg/{f.name[:-4]}": f.read_text() for f in folder.iterdir() if f.name.endswith(".msg")}


@functools.cache
def _specs() -> dict[str, list[tuple[str, str]]]:
    """Field lists by type, keyed both ``pkg/msg/Name`` and ``pkg/Name`` (how fields refer to types)."""
    specs = {}
    for name, text in {**STANDARD_MSGS, **own_msgs()}.items():
        fields = parse_msg(text)
        specs[name] = specs[name.replace("/msg/", "/")] = fields
    return specs


def ros_type(type_name: str) -> str:
    """The ROS 2 type of a handflow message type (``handflow.Label`` → ``handflow_msgs/msg/Label``)."""
    if type_name in STANDARD_TYPES:
        return STANDARD_TYPES[type_name]
    ros = f"{OWN_PACKAGE}/msg/{type_name.rpartition('.')[2]}"
    if ros not in own_msgs():
        raise MessageError(f"message type {type_name} has no ROS 2 definition; add {ros.rpartition('/')[2]}.msg")
    return ros


@functools.cache
def handflow_type(ros: str) -> type[Message]:
    """The handflow message class of a ROS 2 type name (inverse of :func:`ros_type`)."""
    for cls in message_types().values():
        try:
            if ros_type(cls.TYPE) == ros:
                return cls
        except MessageError:
            continue
    raise MessageError(f"no handflow message type for ROS 2 type {ros}")


def type_hash(ros: str) -> str:
    """The RIHS01 hash of a standard or ``handflow_msgs`` type used by the mapping (docs/ros2.md)."""
    return rihs01(ros, {**STANDARD_MSGS, **own_msgs()})


# ----------------------------------------------------------------------------------------------
# Field mapping: handflow message ⇄ values of the ROS message (dicts; header as (stamp_ns, frame_id))
# ----------------------------------------------------------------------------------------------
def _joint_state_to(m: JointState) -> dict[str, Any]:
    return {
        "header": (m.header.stamp_ns, f"{m.hand}/{m.handedness}"),
        "name": m.names,
        "position": m.positions,
        "velocity": m.velocities,
        "effort": (),
    }


def _joint_state_from(v: dict[str, Any]) -> dict[str, Any]:
    hand, sep, handedness = v["header"][1].rpartition("/")
    if not sep:  # a frame_id from another ROS 2 system
        hand, handedness = handedness, ""
    return {
        "names": v["name"],
        "positions": v["position"],
        "velocities": v["velocity"],
        "hand": hand,
        "handedness": handedness,
    }


def _image_to(m: Image) -> dict[str, Any]:
    return {
        "header": (m.header.stamp_ns, m.frame_id),
        "height": m.height,
        "width": m.width,
        "encoding": m.encoding,
        "is_bigendian": 0,
        "step": m.step,
        "data": np.frombuffer(m.data, np.uint8),
    }


def _image_from(v: dict[str, Any]) -> dict[str, Any]:
    return {
        "frame_id": v["header"][1],
        **{k: v[k] for k in ("height", "width", "encoding", "step")},
        "data": v["data"].tobytes(),
    }


def _status_to(m: Status) -> dict[str, Any]:
    status = {
        "level": DIAGNOSTIC_LEVELS.get(m.state, 0),
        "name": m.state,
        "message": m.text,
        "hardware_id": m.header.source,
        "values": [{"key": k, "value": repr(float(v))} for k, v in m.counters.items()],
    }
    return {"header": (m.header.stamp_ns, ""), "status": [status]}


def _status_from(v: dict[str, Any]) -> dict[str, Any]:
    if len(v["status"]) != 1:
        raise MessageError(f"a handflow Status is a DiagnosticArray with one status, got {len(v['status'])}")
    (s,) = v["status"]
    try:
        counters = {kv["key"]: float(kv["value"]) for kv in s["values"]}
    except ValueError as exc:
        raise MessageError(f"diagnostic values must be numbers: {exc}") from None
    return {"state": s["name"], "text": s["message"], "counters": counters}


def _own_to(m: Message) -> dict[str, Any]:
    v = {name: getattr(m, name) for name in vars(m) if name != "header"}
    v["header"] = (m.header.stamp_ns, "")
    return v


def _own_from(v: dict[str, Any]) -> dict[str, Any]:
    return {k: val for k, val in v.items() if k != "header"}


def _glove_to(m: Message) -> dict[str, Any]:
    v = _own_to(m)
    for name in ("device_time", "status"):
        v[f"has_{name}"] = v[name] is not None
        v[name] = v[name] or 0
    return v


def _glove_from(v: dict[str, Any]) -> dict[str, Any]:
    out = _own_from(v)
    for name in ("device_time", "status"):
        out[name] = out[name] if out.pop(f"has_{name}") else None
    return out


def _array_from(v: dict[str, Any]) -> dict[str, Any]:
    return {**_own_from(v), "shape": v["shape"].tolist()}


def _points_to(m: Message) -> dict[str, Any]:
    return {**_own_to(m), "points": m.points.reshape(-1)}


def _points_from(v: dict[str, Any]) -> dict[str, Any]:
    out = _own_from(v)
    if out["points"].size % 2:
        raise MessageError(f"Points2D needs x, y pairs, got {out['points'].size} values")
    out["points"] = out["points"].reshape(-1, 2)
    return out


Mapping = tuple[Callable[[Any], dict[str, Any]], Callable[[dict[str, Any]], dict[str, Any]]]
_MAPPINGS: dict[str, Mapping] = {
    JointState.TYPE: (_joint_state_to, _joint_state_from),
    Image.TYPE: (_image_to, _image_from),
    Status.TYPE: (_status_to, _status_from),
    "handflow.GloveFrame": (_glove_to, _glove_from),
    "handflow.Points2D": (_points_to, _points_from),
    "handflow.Array": (_own_to, _array_from),
}


def encode_cdr(msg: Message) -> bytes:
    """The CDR bytes of a message's ROS 2 counterpart (source and seq are not in the body)."""
    to_ros = _MAPPINGS.get(msg.TYPE, (_own_to,))[0]
    w = CdrWriter(_specs())
    w.struct(ros_type(msg.TYPE), to_ros(msg))
    return bytes(w.buf)


def decode_cdr(data: bytes | bytearray | memoryview, type_name: str, source: str = "", seq: int = 0) -> Message:
    """A checked message from CDR bytes of ``type_name`` (handflow or ROS 2 name); :class:`MessageError` otherwise."""
    cls = handflow_type(type_name) if "/" in type_name else message_types().get(type_name)
    if cls is None:
        raise MessageError(f"unknown message type {type_name!r}")
    reader = CdrReader(data, _specs())
    values = reader.struct(ros_type(cls.TYPE))
    reader.finish()
    from_ros = _MAPPINGS.get(cls.TYPE, (None, _own_from))[1]
    try:
        msg = cls(**from_ros(values))
    except (TypeError, ValueError, OverflowError) as exc:
        raise MessageError(f"invalid {cls.TYPE}: {exc}") from None
    msg.header = Header(source, seq, values["header"][0])
    try:
        msg.check()
    except (TypeError, ValueError, OverflowError, IndexError) as exc:
        raise MessageError(f"invalid {cls.TYPE}: {exc}") from None
    return msg


@functools.cache
def schema_text(type_name: str) -> str:
    """The ``ros2msg`` schema of a handflow or ROS 2 type: its definition, then each dependency under a separator."""
    root = ros_type(type_name) if "/" not in type_name else type_name
    order: list[str] = []

    def visit(name: str) -> None:
        full = name if "/msg/" in name else name.replace("/", "/msg/")
        if full in order:
            return
        order.append(full)
        for ftype, _ in _specs()[full]:
            base = ftype.removesuffix("[]")
            if "/" in base:
                visit(base)

    visit(root)
    texts = {**STANDARD_MSGS, **own_msgs()}
    parts = [_definition(texts[root])]
    for dep in order[1:]:
        parts.append("=" * 80 + f"\nMSG: {dep.replace('/msg/', '/')}\n{_definition(texts[dep])}")
    return "\n".join(parts) + "\n"


def _definition(text: str) -> str:
    """Fields and constants without comments, as rosbag2 stores them."""
    lines = (" ".join(line.split("#", 1)[0].split()) for line in text.splitlines())
    return "\n".join(line for line in lines if line)
