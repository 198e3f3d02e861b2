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
CompressedImage              ``sensor_msgs/msg/CompressedImage``
Transforms                   ``tf2_msgs/msg/TFMessage`` (every transform carries the message's stamp)
Markers                      ``visualization_msgs/msg/MarkerArray`` (shapes and texts; no points, meshes
                             or textures; action ADD, lifetime forever)
Text                         ``std_msgs/msg/String`` (no header: the stamp is not carried)
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

import ctypes
import functools
import struct
from collections.abc import Callable
from importlib import resources
from typing import Any

import numpy as np

from ..messages import (
    MARKER_KINDS,
    CompressedImage,
    Header,
    Image,
    JointState,
    Markers,
    Message,
    MessageError,
    Status,
    Text,
    Transforms,
    message_types,
)
from .cdr import HEADER, CdrReader, CdrWriter, parse_msg
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
    "builtin_interfaces/msg/Duration": "int32 sec\nuint32 nanosec",
    "std_msgs/msg/String": "string data",
    "std_msgs/msg/ColorRGBA": "float32 r\nfloat32 g\nfloat32 b\nfloat32 a",
    "sensor_msgs/msg/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data",
    "geometry_msgs/msg/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/msg/Point": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/msg/Quaternion": "float64 x\nfloat64 y\nfloat64 z\nfloat64 w",
    "geometry_msgs/msg/Pose": "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation",
    "geometry_msgs/msg/Transform": "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation",
    "geometry_msgs/msg/TransformStamped": (
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform"
    ),
    "tf2_msgs/msg/TFMessage": "geometry_msgs/TransformStamped[] transforms",
    "visualization_msgs/msg/UVCoordinate": "float32 u\nfloat32 v",
    "visualization_msgs/msg/MeshFile": "string filename\nuint8[] data",
    "visualization_msgs/msg/Marker": (
        "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\nint32 LINE_LIST=5\n"
        "int32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\nint32 TEXT_VIEW_FACING=9\nint32 MESH_RESOURCE=10\n"
        "int32 TRIANGLE_LIST=11\nint32 ARROW_STRIP=12\nint32 ADD=0\nint32 MODIFY=0\nint32 DELETE=2\nint32 DELETEALL=3\n"
        "std_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\ngeometry_msgs/Pose pose\n"
        "geometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\nbuiltin_interfaces/Duration lifetime\nbool frame_locked\n"
        "geometry_msgs/Point[] points\nstd_msgs/ColorRGBA[] colors\nstring texture_resource\n"
        "sensor_msgs/CompressedImage texture\nvisualization_msgs/UVCoordinate[] uv_coordinates\nstring text\n"
        "string mesh_resource\nvisualization_msgs/MeshFile mesh_file\nbool mesh_use_embedded_materials"
    ),
    "visualization_msgs/msg/MarkerArray": "visualization_msgs/Marker[] markers",
}
STANDARD_TYPES = {
    JointState.TYPE: "sensor_msgs/msg/JointState",
    Image.TYPE: "sensor_msgs/msg/Image",
    Status.TYPE: "diagnostic_msgs/msg/DiagnosticArray",
    CompressedImage.TYPE: "sensor_msgs/msg/CompressedImage",
    Transforms.TYPE: "tf2_msgs/msg/TFMessage",
    Markers.TYPE: "visualization_msgs/msg/MarkerArray",
    Text.TYPE: "std_msgs/msg/String",
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
        "data": _pixels(v["data"]),
    }


def _pixels(data: np.ndarray) -> bytes | np.ndarray:
    """An image's ``data``: ``bytes``, but decoded in place from a shared-memory sample of the local
    transport a read-only view that keeps the sample alive (docs/shared_memory.md)."""
    owner = getattr(data.base, "obj", None)  # what the decoded buffer views
    return data if isinstance(owner, ctypes.Array) and not data.flags.writeable else data.tobytes()


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


def _compressed_to(m: CompressedImage) -> dict[str, Any]:
    return {"header": (m.header.stamp_ns, m.frame_id), "format": m.format, "data": np.frombuffer(m.data, np.uint8)}


def _compressed_from(v: dict[str, Any]) -> dict[str, Any]:
    return {"frame_id": v["header"][1], "format": v["format"], "data": v["data"].tobytes()}


_XYZ, _XYZW = ("x", "y", "z"), ("x", "y", "z", "w")


def _fields(row: np.ndarray, names: tuple[str, ...]) -> dict[str, float]:
    return dict(zip(names, row.tolist()))


def _rows(items: list[dict[str, Any]], names: tuple[str, ...]) -> np.ndarray:
    return np.array([[d[k] for k in names] for d in items], dtype=float).reshape(-1, len(names))


def _transforms_to(m: Transforms) -> dict[str, Any]:
    stamp = m.header.stamp_ns
    return {
        "transforms": [
            {
                "header": (stamp, parent),
                "child_frame_id": child,
                "transform": {"translation": _fields(t, _XYZ), "rotation": _fields(r, _XYZW)},
            }
            for parent, child, t, r in zip(m.parents, m.children, m.translations, m.rotations)
        ]
    }


def _transforms_from(v: dict[str, Any]) -> dict[str, Any]:
    ts = v["transforms"]
    return {
        "parents": [t["header"][1] for t in ts],
        "children": [t["child_frame_id"] for t in ts],
        "translations": _rows([t["transform"]["translation"] for t in ts], _XYZ),
        "rotations": _rows([t["transform"]["rotation"] for t in ts], _XYZW),
    }


_RGBA = ("r", "g", "b", "a")
_MARKER_KIND_NAMES = {code: name for name, code in MARKER_KINDS.items()}
_NO_TEXTURE = {"header": (0, ""), "format": "", "data": np.zeros(0, np.uint8)}
_NO_MESH = {"filename": "", "data": np.zeros(0, np.uint8)}


def _markers_to(m: Markers) -> dict[str, Any]:
    stamp = m.header.stamp_ns
    rows = zip(
        m.kinds, m.frame_ids, m.namespaces, m.ids.tolist(), m.positions, m.orientations, m.scales, m.colours, m.texts
    )
    return {
        "markers": [
            {
                "header": (stamp, frame),
                "ns": ns,
                "id": ident,
                "type": MARKER_KINDS[kind],
                "action": 0,
                "pose": {"position": _fields(p, _XYZ), "orientation": _fields(q, _XYZW)},
                "scale": _fields(s, _XYZ),
                "color": _fields(c, _RGBA),
                "lifetime": {"sec": 0, "nanosec": 0},
                "frame_locked": False,
                "points": [],
                "colors": [],
                "texture_resource": "",
                "texture": _NO_TEXTURE,
                "uv_coordinates": [],
                "text": text,
                "mesh_resource": "",
                "mesh_file": _NO_MESH,
                "mesh_use_embedded_materials": False,
            }
            for kind, frame, ns, ident, p, q, s, c, text in rows
        ]
    }


def _markers_from(v: dict[str, Any]) -> dict[str, Any]:
    ms = v["markers"]
    for mk in ms:
        if mk["type"] not in _MARKER_KIND_NAMES or mk["action"] != 0:
            raise MessageError(
                f"handflow Markers carry added {', '.join(MARKER_KINDS)} markers; got type {mk['type']}, action {mk['action']}"
            )
        if mk["points"] or mk["texture"]["data"].size or mk["mesh_file"]["data"].size:
            raise MessageError("handflow Markers carry no points, textures or meshes")
    return {
        "kinds": [_MARKER_KIND_NAMES[mk["type"]] for mk in ms],
        "frame_ids": [mk["header"][1] for mk in ms],
        "namespaces": [mk["ns"] for mk in ms],
        "ids": np.array([mk["id"] for mk in ms], dtype=np.int32),
        "positions": _rows([mk["pose"]["position"] for mk in ms], _XYZ),
        "orientations": _rows([mk["pose"]["orientation"] for mk in ms], _XYZW),
        "scales": _rows([mk["scale"] for mk in ms], _XYZ),
        "colours": _rows([mk["color"] for mk in ms], _RGBA).astype(np.float32),
        "texts": [mk["text"] for mk in ms],
    }


def _stamp_of_first(items: str) -> Callable[[dict[str, Any]], int]:
    """Stamp of a headerless ROS type: that of its first element (0 when empty)."""
    return lambda v: v[items][0]["header"][0] if v[items] else 0


STAMPS: dict[str, Callable[[dict[str, Any]], int]] = {
    Transforms.TYPE: _stamp_of_first("transforms"),
    Markers.TYPE: _stamp_of_first("markers"),
    Text.TYPE: lambda v: 0,
}
"""How to find the stamp of types whose ROS 2 message does not start with ``std_msgs/Header``."""


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
    CompressedImage.TYPE: (_compressed_to, _compressed_from),
    Transforms.TYPE: (_transforms_to, _transforms_from),
    Markers.TYPE: (_markers_to, _markers_from),
    Text.TYPE: (lambda m: {"data": m.data}, lambda v: {"data": v["data"]}),
}


def encode_cdr(msg: Message) -> bytes:
    """The CDR bytes of a message's ROS 2 counterpart (source and seq are not in the body)."""
    to_ros = _MAPPINGS.get(msg.TYPE, (_own_to,))[0]
    w = CdrWriter(_specs())
    w.struct(ros_type(msg.TYPE), to_ros(msg))
    return bytes(w.buf)


_SOURCE_IN_BODY = {Status.TYPE}  # types whose body holds the header's source node (``hardware_id``)
_STAMP = struct.Struct("<iI")


def restamped_cdr(body: bytes, type_name: str, stamp_ns: int) -> bytes | None:
    """The CDR ``body`` of a ``type_name`` message (as :func:`encode_cdr` or a peer wrote it) with
    the header stamp set to ``stamp_ns``; ``None`` for types whose body holds more of the header
    than the stamp, or no header first (docs/ros2.md, "Forwarding")."""
    if not _restampable(type_name):
        return None
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    if _STAMP.unpack_from(body, 4) == (sec, nanosec):
        return body
    out = bytearray(body)
    try:
        _STAMP.pack_into(out, 4, sec, nanosec)
    except struct.error as exc:
        raise MessageError(f"stamp {stamp_ns} ns does not fit a ROS 2 time: {exc}") from None
    return bytes(out)


@functools.cache
def _restampable(type_name: str) -> bool:
    return (
        type_name not in STAMPS and type_name not in _SOURCE_IN_BODY and _specs()[ros_type(type_name)][0][0] == HEADER
    )


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
    stamp = STAMPS[cls.TYPE](values) if cls.TYPE in STAMPS else values["header"][0]
    msg.header = Header(source, seq, stamp)
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
