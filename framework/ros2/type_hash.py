"""RIHS01 type hashes of ROS 2 message types from their ``.msg`` definitions (REP-2016; docs/ros2.md).

A type's hash is the SHA-256 of its *type description* written as compact JSON: the type's fields
and, sorted by name, every type it refers to (transitively), each field as ``name`` plus
``type_id`` / ``capacity`` / ``string_capacity`` / ``nested_type_name`` (default values are not
hashed).  rmw_zenoh puts the hash in every key expression, so a subscriber only matches a publisher
of the same definition.  Cross-checked against ``rosbags`` for every type of its Jazzy store and
against published hashes in tests/framework/test_ros2_interop.py.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Mapping

from ..messages import MessageError

# type_description_interfaces/msg/FieldType
_TYPE_IDS = {
    "int8": 2,
    "uint8": 3,
    "char": 3,  # ROS 2 .msg ``char`` is uint8
    "int16": 4,
    "uint16": 5,
    "int32": 6,
    "uint32": 7,
    "int64": 8,
    "uint64": 9,
    "float32": 10,
    "float64": 11,
    "bool": 15,
    "byte": 16,
    "string": 17,
    "wstring": 18,
}
_NESTED, _BOUNDED_STRING = 1, {"string": 21, "wstring": 22}
_FIXED_ARRAY, _BOUNDED_SEQUENCE, _SEQUENCE = 48, 96, 144
_FIELD = re.compile(r"^(?P<base>[\w/]+?)(?:<=(?P<strcap>\d+))?(?P<array>\[(?P<bound><=)?(?P<n>\d*)\])?$")


def _field_type(ftype: str, package: str) -> dict[str, object]:
    m = _FIELD.match(ftype)
    if m is None:
        raise MessageError(f"cannot read the field type {ftype!r}")
    base, strcap = m["base"], int(m["strcap"] or 0)
    nested = ""
    if base in _TYPE_IDS:
        type_id = _BOUNDED_STRING[base] if strcap else _TYPE_IDS[base]
    else:
        type_id = _NESTED
        nested = full_name(base if "/" in base else f"{package}/{base}")
        if base == "Header":
            nested = "std_msgs/msg/Header"
    capacity = 0
    if m["array"]:
        if not m["n"]:
            type_id += _SEQUENCE
        else:
            type_id += _BOUNDED_SEQUENCE if m["bound"] else _FIXED_ARRAY
            capacity = int(m["n"])
    return {"type_id": type_id, "capacity": capacity, "string_capacity": strcap, "nested_type_name": nested}


def full_name(name: str) -> str:
    """``pkg/Name`` or ``pkg/msg/Name`` → ``pkg/msg/Name``."""
    pkg, _, rest = name.partition("/")
    return name if "/" in rest else f"{pkg}/msg/{rest}"


def _fields(type_name: str, text: str) -> list[dict[str, object]]:
    package = type_name.partition("/")[0]
    fields = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split(None, 2)
        if len(parts) < 2 or "=" in parts[1] or (len(parts) == 3 and parts[2].startswith("=")):
            continue  # a constant
        fields.append({"name": parts[1], "type": _field_type(parts[0], package)})
    if not fields:  # rosidl adds a placeholder member to empty structures
        fields.append({"name": "structure_needs_at_least_one_member", "type": _field_type("uint8", package)})
    return fields


def type_description(type_name: str, texts: Mapping[str, str]) -> dict[str, object]:
    """The hashed part of a type description: the type's fields and those of every type it refers to."""
    root = full_name(type_name)
    described: dict[str, list[dict[str, object]]] = {}
    todo = [root]
    while todo:
        name = todo.pop()
        if name in described:
            continue
        if name not in texts:
            raise MessageError(f"no definition of {name} (needed by {root}); give its .msg file")
        described[name] = _fields(name, texts[name])
        todo += [str(f["type"]["nested_type_name"]) for f in described[name] if f["type"]["nested_type_name"]]  # type: ignore[index]
    refs = [{"type_name": n, "fields": described[n]} for n in sorted(described) if n != root]
    return {"type_description": {"type_name": root, "fields": described[root]}, "referenced_type_descriptions": refs}


def rihs01(type_name: str, texts: Mapping[str, str]) -> str:
    """``RIHS01_<sha256 hex>`` of a type; ``texts`` maps ``pkg/msg/Name`` to ``.msg`` text (dependencies included)."""
    body = json.dumps(type_description(type_name, texts), separators=(", ", ": "), ensure_ascii=True)
    return "RIHS01_" + hashlib.sha256(body.encode()).hexdigest()
