"""Malformed payloads for robustness tests and benchmarks: mutations of real encoded messages.

Used by the property tests (hypothesis draws the mutations), ``benchmarks/decode_fuzz.py`` and the
garbage end-to-end test (docs/robustness.md).  A :class:`Mutation` is plain data (operation, a
position in [0, 1), a value index), so hypothesis can shrink it and a seeded generator can draw it.

Operations on the JSON structure (the target is the node at ``position`` in a depth-first walk):
``extreme`` (replace by one of :data:`EXTREMES`: huge/tiny numbers, NaN/inf, int64 edges, wrong
kinds), ``empty`` (empty a list/object/string), ``repeat`` (repeat a list's items or a string),
``drop`` (remove the node), ``nest`` (wrap it in a list).  Operations on the bytes: ``flip`` (XOR a
byte), ``cut`` (truncate), ``insert`` (insert a byte).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..messages import (
    Array,
    CompressedImage,
    Contacts,
    GloveFrame,
    Image,
    JointState,
    Label,
    LatentState,
    Markers,
    Message,
    ParamChange,
    Points2D,
    RuntimeEvent,
    SegmentEvent,
    Status,
    Text,
    Transforms,
    encode,
    message_types,
)

EXTREMES: tuple[Any, ...] = (
    1e308,
    -1e308,
    float("nan"),
    float("inf"),
    5e-324,
    2**63,
    -(2**63) - 1,
    2**64 + 1,
    10**400,
    -1,
    0,
    True,
    None,
    "",
    "x" * 4096,
    "\udcff",
    [],
    {},
    [[1, 2], [3]],
)
JSON_OPS = ("extreme", "empty", "repeat", "drop", "nest")
BYTE_OPS = ("flip", "cut", "insert")
OPS = JSON_OPS + BYTE_OPS


@dataclass(frozen=True)
class Mutation:
    op: str
    position: float  # in [0, 1): which JSON node or byte
    value: int  # index into EXTREMES / byte value / repeat count


def sample_messages() -> list[Message]:
    """One realistic message of every registered type (types defined by plugins: their defaults)."""
    rng = np.random.default_rng(0)
    examples: list[Message] = [
        Array(data=rng.normal(size=(2, 3)), names=list("abcdef")),
        JointState(names=[f"J{i}" for i in range(24)], positions=rng.uniform(-1, 1, 24), hand="shadow"),
        GloveFrame(sensors=rng.integers(0, 256, 22), device_time=123, status=1, arrival_ns=99),
        Contacts(segments=["ffdistal", "thdistal"], bodies=["cap", "cap"], forces=[1.5, 0.2]),
        Points2D(points=[[0.5, 0.1], [np.nan, np.nan]], valid=[True, False], ids=[3, 4]),
        Image.from_array(rng.integers(0, 256, (6, 8, 3), dtype=np.uint8)),
        LatentState(manifold="cap", coords=[1.0, 0.3], error=0.01),
        Label(label="grasp", index=4, classes=["grasp", "wave"], scores=[0.9, -0.2]),
        SegmentEvent(kind="revision", label="wave", start_index=3, end_index=9, previous_label="grasp"),
        Status(state="connected", counters={"corrupt": 2.0}, text="ok"),
        RuntimeEvent(kind="dropped", node="human", topic="handflow/demo/glove/frames", count=3, detail="bad"),
        ParamChange(node="segmenter", key="threshold", value="0.4", previous="null", restart=True),
        CompressedImage(format="jpeg", data=b"\xff\xd8\xff\xe0 not really a jpeg", frame_id="cap_camera"),
        Transforms(
            parents=["world", "sim/forearm"],
            children=["sim/forearm", "sim/wrist"],
            translations=[[0.0, 0.1, 0.2], [0.0, 0.0, 0.0]],
            rotations=[[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, np.sin(0.3), np.cos(0.3)]],
        ),
        Markers(
            kinds=["sphere", "text"],
            frame_ids=["world", "world"],
            namespaces=["balls", "label"],
            ids=[1, 0],
            positions=[[0.1, 0.0, 0.3], [0.0, 0.0, 0.5]],
            orientations=[[0.0, 0.0, 0.0, 1.0]] * 2,
            scales=[[0.04, 0.04, 0.04], [0.0, 0.0, 0.05]],
            colours=[[1.0, 0.2, 0.2, 1.0], [1.0, 1.0, 1.0, 1.0]],
            texts=["", "grasp"],
        ),
        Text(data='<?xml version="1.0"?><robot name="x"/>'),
    ]
    known = {type(m) for m in examples}
    examples += [cls() for cls in message_types().values() if cls not in known]
    for seq, msg in enumerate(examples, 1):
        msg.header.source, msg.header.seq, msg.header.stamp_ns = "fuzz", seq, 1_700_000_000_000_000_000 + seq
    return examples


def _nodes(value: Any, parent: Any = None, key: Any = None) -> Iterator[tuple[Any, Any, Any]]:
    """(parent, key, value) of every JSON node, depth first (the root has parent None)."""
    yield parent, key, value
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _nodes(v, value, k)
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _nodes(v, value, i)


def _mutate_json(doc: Any, m: Mutation) -> Any:
    nodes = list(_nodes(doc))
    parent, key, value = nodes[int(m.position * len(nodes))]
    if m.op == "extreme":
        new = EXTREMES[m.value % len(EXTREMES)]
    elif m.op == "empty":
        new = type(value)() if isinstance(value, (list, dict, str)) else value
    elif m.op == "repeat":
        new = value * (2 + m.value % 50) if isinstance(value, (list, str)) else value
    elif m.op == "nest":
        new = [value]
    else:  # drop
        if parent is None:
            return None
        del parent[key]
        return doc
    if parent is None:
        return new
    parent[key] = new
    return doc


def mutate(payload: bytes, mutations: list[Mutation]) -> bytes:
    """Apply ``mutations`` in order (JSON operations re-serialise; NaN/inf become JSON's literals)."""
    data = bytes(payload)
    for m in mutations:
        if m.op in JSON_OPS:
            try:
                doc = json.loads(data)
            except ValueError:
                continue  # a byte operation broke the JSON already
            text = json.dumps(_mutate_json(doc, m), separators=(",", ":"), ensure_ascii=m.value % 2 == 0)
            data = text.encode("utf-8", "surrogatepass")
            continue
        i = int(m.position * len(data))
        if m.op == "flip" and data:
            data = data[:i] + bytes([data[i] ^ (1 + m.value % 255)]) + data[i + 1 :]
        elif m.op == "cut":
            data = data[:i]
        elif m.op == "insert":
            data = data[:i] + bytes([m.value % 256]) + data[i:]
    return data


def random_mutations(rng: np.random.Generator, max_count: int = 3) -> list[Mutation]:
    """1..``max_count`` mutations drawn from ``rng``."""
    n = int(rng.integers(1, max_count + 1))
    return [
        Mutation(OPS[int(rng.integers(len(OPS)))], float(rng.random()), int(rng.integers(1 << 16))) for _ in range(n)
    ]


def malformed_payloads(n: int, seed: int = 0, seeds: list[bytes] | None = None) -> Iterator[bytes]:
    """``n`` payloads: mutated copies of ``seeds`` (default: :func:`sample_messages` encoded)."""
    rng = np.random.default_rng(seed)
    seeds = seeds or [encode(m) for m in sample_messages()]
    for _ in range(n):
        yield mutate(seeds[int(rng.integers(len(seeds)))], random_mutations(rng))
