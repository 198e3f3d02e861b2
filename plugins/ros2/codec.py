"""Conversion between a ROS 2 message type's CDR and handflow messages (docs/ros2.md).

Types with a handflow counterpart (``sensor_msgs/msg/JointState``, ``sensor_msgs/msg/Image``,
``diagnostic_msgs/msg/DiagnosticArray``, ``handflow_msgs/msg/*``) become that message, decoded by
handflow's own CDR codec.  Any other type — from the ``rosbags`` Jazzy type store or given as
``.msg`` files — becomes an :class:`~handflow.framework.messages.Array` of its numeric fields,
flattened with dotted names (``pose.position.x``, ``data[3]``; strings are left out), and is written
back from one; that needs the ``ros2`` extra (``pip install 'handflow[ros2]'``).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from handflow.framework.messages import Array, Header, Message, MessageError
from handflow.framework.ros2 import types
from handflow.framework.ros2.type_hash import full_name, rihs01

HEADER = "std_msgs/msg/Header"
_INDEX = re.compile(r"^(\w+)(?:\[(\d+)\])?$")
_NUMPY = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "uint8": np.uint8,
    "int8": np.int8,
    "uint16": np.uint16,
    "int16": np.int16,
    "uint32": np.uint32,
    "int32": np.int32,
    "uint64": np.uint64,
    "int64": np.int64,
    "float32": np.float32,
    "float64": np.float64,
}


def _typestore(msg_files: Iterable[Path]):
    try:
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    except ImportError:
        raise MessageError(
            "ROS 2 types other than handflow's own need the 'ros2' extra: pip install 'handflow[ros2]'"
        ) from None
    store = get_typestore(Stores.ROS2_JAZZY)
    for path in msg_files:
        parts = Path(path).with_suffix("").parts
        if len(parts) < 3 or parts[-2] != "msg" or Path(path).suffix != ".msg":
            raise MessageError(f"a .msg file must live at <package>/msg/<Name>.msg, got {path}")
        try:
            text = Path(path).read_text()
            store.register(get_types_from_msg(text, "/".join(parts[-3:])))
        except (OSError, ValueError, KeyError) as exc:
            raise MessageError(f"cannot load {path}: {exc}") from None
    return store


def _texts(store, name: str) -> dict[str, str]:
    """``pkg/msg/Name`` → ``.msg`` text of a type and its dependencies, as the type store writes them."""
    text, _ = store.generate_msgdef(name, ros_version=2)
    first, *deps = text.split("=" * 80 + "\n")
    out = {name: first}
    for dep in deps:
        head, _, body = dep.partition("\n")
        out[full_name(head.removeprefix("MSG: ").strip())] = body
    return out


def native_type(ros_type: str) -> type[Message] | None:
    """The handflow counterpart of a ROS 2 type, if it has one."""
    try:
        return types.handflow_type(full_name(ros_type))
    except MessageError:
        return None


class RosCodec:
    """CDR of one ROS 2 type ⇄ handflow messages; ``message_type`` and ``type_hash`` tell what and how."""

    def __init__(self, ros_type: str, msg_files: Iterable[Path] = ()) -> None:
        self.ros_type = full_name(ros_type)
        native = native_type(self.ros_type)
        self.message_type = native or Array
        if native is not None:
            self.store = None
            self.type_hash = types.type_hash(self.ros_type)
            return
        self.store = _typestore(msg_files)
        if self.ros_type not in self.store.fielddefs:
            raise MessageError(
                f"unknown ROS 2 type {self.ros_type}: not in the Jazzy type store; give its .msg file(s) in 'msg_files'"
            )
        self.type_hash = rihs01(self.ros_type, _texts(self.store, self.ros_type))

    # -- decoding ------------------------------------------------------------------------------
    def decode(self, cdr: bytes, source: str, seq: int, source_timestamp_ns: int) -> Message:
        """A checked message; the stamp is the header's, or the sender's timestamp when the type has none (or 0)."""
        if self.store is None:
            msg = types.decode_cdr(cdr, self.ros_type, source, seq)
            if msg.header.stamp_ns == 0:
                msg.header = Header(source, seq, source_timestamp_ns)
            return msg
        try:
            ros = self.store.deserialize_cdr(cdr, self.ros_type)
        except Exception as exc:  # rosbags raises many kinds on malformed bytes
            raise MessageError(f"malformed {self.ros_type}: {type(exc).__name__}: {str(exc)[:200]}") from None
        names: list[str] = []
        values: list[float] = []
        stamp = _flatten(ros, "", names, values)
        msg = Array(data=np.asarray(values, dtype=np.float64), names=names)
        msg.header = Header(source, seq, stamp or source_timestamp_ns)
        msg.check()
        return msg

    # -- encoding ------------------------------------------------------------------------------
    def encode(self, msg: Message) -> bytes:
        """CDR bytes of ``msg`` as this type (an Array's names address fields, see the module docstring)."""
        if self.store is None:
            if not isinstance(msg, self.message_type):
                raise MessageError(f"{self.ros_type} is published from {self.message_type.TYPE}, got {msg.TYPE}")
            return types.encode_cdr(msg)
        if not isinstance(msg, Array):
            raise MessageError(f"{self.ros_type} is published from handflow.Array, got {msg.TYPE}")
        tree = _template(self.store, self.ros_type)
        names = msg.names or _only_numeric_array(self.store, self.ros_type, msg.data.size)
        for name, value in zip(names, msg.data.tolist()):
            _assign(self.store, self.ros_type, tree, name, value)
        if "header" in tree and isinstance(tree["header"], dict) and tree["header"]["__type"] == HEADER:
            sec, nanosec = divmod(msg.header.stamp_ns, 1_000_000_000)
            tree["header"]["stamp"].update(sec=sec, nanosec=nanosec)
        try:
            return bytes(self.store.serialize_cdr(_build(self.store, tree), self.ros_type))
        except Exception as exc:
            raise MessageError(f"cannot write {self.ros_type}: {type(exc).__name__}: {str(exc)[:200]}") from None


def _flatten(value: Any, prefix: str, names: list[str], values: list[float]) -> int:
    """Append numeric leaves of a rosbags message; returns its header stamp in ns (0 if none)."""
    stamp = 0
    for f in dataclasses.fields(value):
        if f.name == "__msgtype__":
            continue
        v, name = getattr(value, f.name), f"{prefix}{f.name}"
        if getattr(v, "__msgtype__", None) == HEADER and not prefix:
            stamp = v.stamp.sec * 1_000_000_000 + v.stamp.nanosec
        elif dataclasses.is_dataclass(v):
            _flatten(v, name + ".", names, values)
        elif isinstance(v, np.ndarray):
            names += [f"{name}[{i}]" for i in range(v.size)]
            values += v.astype(np.float64).ravel().tolist()
        elif isinstance(v, list):
            for i, item in enumerate(v):
                if dataclasses.is_dataclass(item):
                    _flatten(item, f"{name}[{i}].", names, values)
        elif isinstance(v, (bool, int, float)):
            names.append(name)
            values.append(float(v))
    return stamp


def _default(store, node: tuple) -> Any:
    kind, arg = node
    kind = getattr(kind, "name", kind)
    if kind == "BASE":
        base = arg[0]
        return "" if base in ("string", "wstring") else (False if base == "bool" else 0)
    if kind == "NAME":
        return _template(store, arg)
    sub, n = arg
    numeric = getattr(sub[0], "name", sub[0]) == "BASE" and sub[1][0] in _NUMPY
    count = n if kind == "ARRAY" else 0
    if numeric:
        return np.zeros(count, dtype=_NUMPY[sub[1][0]])
    return [_default(store, sub) for _ in range(count)]


def _template(store, name: str) -> dict[str, Any]:
    """Default values of a type as nested dicts (``__type`` names each struct)."""
    return {"__type": name, **{fname: _default(store, node) for fname, node in store.fielddefs[name][1]}}


def _field_node(store, type_name: str, field: str) -> tuple:
    for fname, node in store.fielddefs[type_name][1]:
        if fname == field:
            return node
    raise MessageError(f"{type_name} has no field '{field}'")


def _assign(store, type_name: str, tree: dict[str, Any], path: str, value: float) -> None:
    head, _, rest = path.partition(".")
    m = _INDEX.match(head)
    if m is None:
        raise MessageError(f"cannot address '{path}' in {type_name}; use dotted names like pose.position.x or data[3]")
    field, index = m[1], m[2]
    node = _field_node(store, type_name, field)
    kind = getattr(node[0], "name", node[0])
    if index is None:
        if kind == "NAME" and rest:
            return _assign(store, node[1], tree[field], rest, value)
        if kind == "BASE" and not rest and node[1][0] not in ("string", "wstring"):
            tree[field] = bool(value) if node[1][0] == "bool" else (value if "float" in node[1][0] else int(value))
            return
        raise MessageError(f"'{path}' does not name a number in {type_name}")
    i, container = int(index), tree[field]
    if kind == "ARRAY" and i >= node[1][1]:
        raise MessageError(f"'{path}': {type_name}.{field} holds {node[1][1]} values")
    if kind not in ("ARRAY", "SEQUENCE"):
        raise MessageError(f"'{path}': {type_name}.{field} is not an array")
    sub = node[1][0]
    if isinstance(container, np.ndarray):
        if rest:
            raise MessageError(f"'{path}' does not name a number in {type_name}")
        if i >= container.size:
            container = tree[field] = np.concatenate([container, np.zeros(i + 1 - container.size, container.dtype)])
        container[i] = value
        return
    while len(container) <= i:
        container.append(_default(store, sub))
    if not rest:
        raise MessageError(f"'{path}' does not name a number in {type_name}")
    _assign(store, sub[1], container[i], rest, value)


def _only_numeric_array(store, name: str, size: int) -> list[str]:
    """Names for an Array without names: the type's single numeric array field (e.g. ``data``)."""
    fields = [(f, n) for f, n in store.fielddefs[name][1] if getattr(n[0], "name", n[0]) in ("ARRAY", "SEQUENCE")]
    numeric = [f for f, n in fields if getattr(n[1][0][0], "name", n[1][0][0]) == "BASE" and n[1][0][1][0] in _NUMPY]
    if len(numeric) != 1:
        raise MessageError(f"an Array published as {name} needs 'names' (dotted field names) for its values")
    return [f"{numeric[0]}[{i}]" for i in range(size)]


def _build(store, tree: Any) -> Any:
    if isinstance(tree, dict):
        cls = store.types[tree["__type"]]
        return cls(**{k: _build(store, v) for k, v in tree.items() if k != "__type"})
    if isinstance(tree, list):
        return [_build(store, v) for v in tree]
    return tree
