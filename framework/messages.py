"""Typed message schemas and the one codec used on the wire and in recordings (spec handflow.framework.md).

Every message carries a :class:`Header` (source node, sequence number, ``stamp_ns``).  Payloads are
plain dataclasses whose array fields are numpy arrays; :func:`encode` turns a message into compact
JSON bytes (``{"type": ..., "header": ..., <fields>}``) and :func:`decode` back.  JSON keeps
recordings readable by Foxglove (JSON-schema channels, see :func:`json_schema`).

Validation (:meth:`Message.check`) rejects NaN/inf and wrongly shaped payloads; the publisher calls
it and names the node and port in the error.
"""

from __future__ import annotations

import base64
import dataclasses
import json
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np


class MessageError(ValueError):
    """A payload that cannot be published or decoded (non-finite, wrong shape, unknown type)."""


@dataclass
class Header:
    """Source node id, per-port sequence number, source time in nanoseconds."""

    source: str = ""
    seq: int = 0
    stamp_ns: int = 0


def _array(dtype: str, ndim: int = 1, *, finite: bool = True, cols: int | None = None) -> Any:
    """Declare an array field: converted to a numpy array of ``dtype`` on construction and decode."""
    return field(
        default_factory=lambda: np.zeros((0,) * ndim if cols is None else (0, cols), dtype=dtype),
        metadata={"array": dtype, "ndim": ndim, "finite": finite, "cols": cols},
    )


_REGISTRY: dict[str, type[Message]] = {}


@dataclass
class Message:
    """Base of all message types; subclasses are dataclasses with a unique ``TYPE`` name."""

    TYPE: ClassVar[str] = ""
    header: Header = field(default_factory=Header, repr=False, compare=False)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.__dict__.get("TYPE"):
            _REGISTRY[cls.TYPE] = cls

    def __post_init__(self) -> None:
        for f in _array_fields(type(self)):
            value = getattr(self, f.name)
            if not isinstance(value, np.ndarray) or value.dtype != np.dtype(f.metadata["array"]):
                setattr(self, f.name, np.asarray(value, dtype=f.metadata["array"]))

    # -- validation -------------------------------------------------------------------------
    def check(self) -> None:
        """Raise :class:`MessageError` if the payload is not publishable."""
        for f in _array_fields(type(self)):
            arr = getattr(self, f.name)
            meta = f.metadata
            if arr.ndim != meta["ndim"]:
                raise MessageError(f"field '{f.name}' must have {meta['ndim']} dimension(s), got shape {arr.shape}")
            if meta["cols"] is not None and arr.size and arr.shape[1] != meta["cols"]:
                raise MessageError(f"field '{f.name}' must have {meta['cols']} columns, got shape {arr.shape}")
            if meta["finite"] and arr.dtype.kind == "f" and not np.isfinite(arr).all():
                bad = int((~np.isfinite(arr)).sum())
                raise MessageError(f"field '{f.name}' holds {bad} NaN/inf value(s)")
        self._check_shapes()

    def _check_shapes(self) -> None:
        """Cross-field shape rules of a subclass."""

    # -- (de)serialisation ------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": self.TYPE, "header": dataclasses.asdict(self.header)}
        for f in dataclasses.fields(self):
            if f.name == "header":
                continue
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray):
                value = value.tolist()
            elif isinstance(value, bytes):
                value = base64.b64encode(value).decode("ascii")
            out[f.name] = value
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Message:
        kwargs = {k: v for k, v in d.items() if k not in ("type", "header") and k in cls.__dataclass_fields__}
        for f in dataclasses.fields(cls):
            if f.type in ("bytes", bytes) and isinstance(kwargs.get(f.name), str):
                kwargs[f.name] = base64.b64decode(kwargs[f.name])
            if f.metadata.get("array") and f.name in kwargs:
                meta = f.metadata
                arr = np.asarray(kwargs[f.name], dtype=meta["array"])
                if arr.size == 0 and meta["ndim"] == 2:
                    arr = arr.reshape(0, meta["cols"] or 0)
                kwargs[f.name] = arr
        msg = cls(**kwargs)
        msg.header = Header(**d.get("header", {}))
        return msg


def _array_fields(cls: type) -> list[dataclasses.Field]:
    cached = cls.__dict__.get("_array_fields_cache")
    if cached is None:
        cached = [f for f in dataclasses.fields(cls) if f.metadata.get("array")]
        cls._array_fields_cache = cached
    return cached


# --------------------------------------------------------------------------------------------
# Concrete message types
# --------------------------------------------------------------------------------------------
@dataclass
class Array(Message):
    """Numeric array (any shape, stored flat with ``shape``); optional element ``names``."""

    TYPE: ClassVar[str] = "handflow.Array"
    data: np.ndarray = _array("float64")
    shape: list[int] = field(default_factory=list)
    names: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        arr = np.asarray(self.data, dtype=np.float64)
        if not self.shape:
            self.shape = list(arr.shape)
        self.data = arr.reshape(-1)

    def _check_shapes(self) -> None:
        if int(np.prod(self.shape)) != self.data.size:
            raise MessageError(f"shape {self.shape} does not match {self.data.size} values")
        if self.names and len(self.names) != self.data.size:
            raise MessageError(f"{len(self.names)} names for {self.data.size} values")

    @property
    def values(self) -> np.ndarray:
        """The data in its declared shape."""
        return self.data.reshape(self.shape)


@dataclass
class JointState(Message):
    """Joint names and positions in radians (velocities optional), hand model and handedness."""

    TYPE: ClassVar[str] = "handflow.JointState"
    names: list[str] = field(default_factory=list)
    positions: np.ndarray = _array("float64")
    velocities: np.ndarray = _array("float64")
    hand: str = ""
    handedness: str = "right"

    def _check_shapes(self) -> None:
        if len(self.names) != self.positions.size:
            raise MessageError(f"{len(self.names)} joint names for {self.positions.size} positions")
        if self.velocities.size not in (0, self.positions.size):
            raise MessageError(f"{self.velocities.size} velocities for {self.positions.size} positions")


@dataclass
class GloveFrame(Message):
    """Raw data-glove record: sensor values (uint8 each), optional device time and status, host arrival time."""

    TYPE: ClassVar[str] = "handflow.GloveFrame"
    sensors: np.ndarray = _array("int64")
    device_time: int | None = None
    status: int | None = None
    arrival_ns: int = 0

    def _check_shapes(self) -> None:
        if self.sensors.size and (self.sensors.min() < 0 or self.sensors.max() > 255):
            raise MessageError("sensor values must lie in 0..255")


@dataclass
class Contacts(Message):
    """One entry per contact: the hand segment, the body it touches and the normal force (N)."""

    TYPE: ClassVar[str] = "handflow.Contacts"
    segments: list[str] = field(default_factory=list)
    bodies: list[str] = field(default_factory=list)
    forces: np.ndarray = _array("float64")

    def _check_shapes(self) -> None:
        if not len(self.segments) == len(self.bodies) == self.forces.size:
            raise MessageError("segments, bodies and forces must have one entry per contact")


@dataclass
class Points2D(Message):
    """2D points with per-point validity (a tracker never invents a missing point) and track ids."""

    TYPE: ClassVar[str] = "handflow.Points2D"
    points: np.ndarray = _array("float64", 2, cols=2, finite=False)
    valid: np.ndarray = _array("bool")
    ids: np.ndarray = _array("int64")

    def _check_shapes(self) -> None:
        n = self.points.shape[0]
        if self.valid.size != n or self.ids.size not in (0, n):
            raise MessageError("points, valid and ids must have one entry per point")
        if not np.isfinite(self.points[self.valid]).all():
            raise MessageError("a valid point holds NaN/inf")

    def to_dict(self) -> dict[str, Any]:
        d = super().to_dict()  # invalid points travel as null (JSON has no NaN)
        d["points"] = [p if ok else None for p, ok in zip(d["points"], self.valid.tolist())]
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Message:
        d = dict(d, points=[[np.nan, np.nan] if p is None else p for p in d.get("points", [])])
        return super().from_dict(d)


@dataclass
class Image(Message):
    """Raw image, field names as Foxglove's ``foxglove.RawImage`` (data base64 in JSON)."""

    TYPE: ClassVar[str] = "handflow.Image"
    width: int = 0
    height: int = 0
    encoding: str = "rgb8"
    step: int = 0
    data: bytes = b""
    frame_id: str = "camera"

    def _check_shapes(self) -> None:
        if self.step * self.height != len(self.data):
            raise MessageError(
                f"image of {self.height} rows × step {self.step} needs {self.step * self.height} bytes, got {len(self.data)}"
            )

    @classmethod
    def from_array(cls, rgb: np.ndarray, frame_id: str = "camera") -> Image:
        rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
        h, w = rgb.shape[:2]
        channels = 1 if rgb.ndim == 2 else rgb.shape[2]
        enc = {1: "mono8", 3: "rgb8", 4: "rgba8"}[channels]
        return cls(width=w, height=h, encoding=enc, step=w * channels, data=rgb.tobytes(), frame_id=frame_id)

    def to_array(self) -> np.ndarray:
        channels = self.step // max(self.width, 1)
        arr = np.frombuffer(self.data, dtype=np.uint8).reshape(self.height, self.width, channels)
        return arr[:, :, 0] if channels == 1 else arr


@dataclass
class LatentState(Message):
    """Position on a manifold: manifold id, latent coordinates, reconstruction error."""

    TYPE: ClassVar[str] = "handflow.LatentState"
    manifold: str = ""
    coords: np.ndarray = _array("float64")
    error: float = 0.0


@dataclass
class Label(Message):
    """Per-sample label (``"unknown"`` when rejected) with optional per-class scores."""

    TYPE: ClassVar[str] = "handflow.Label"
    label: str = "unknown"
    index: int = 0
    classes: list[str] = field(default_factory=list)
    scores: np.ndarray = _array("float64")

    def _check_shapes(self) -> None:
        if self.scores.size and self.scores.size != len(self.classes):
            raise MessageError(f"{self.scores.size} scores for {len(self.classes)} classes")


@dataclass
class SegmentEvent(Message):
    """Segment start/end, or a revision of an earlier decision (``previous_label`` set)."""

    TYPE: ClassVar[str] = "handflow.SegmentEvent"
    kind: str = "start"  # start | end | revision
    label: str = "unknown"
    start_index: int = 0
    end_index: int = 0
    previous_label: str = ""

    def _check_shapes(self) -> None:
        if self.kind not in ("start", "end", "revision"):
            raise MessageError(f"kind must be start, end or revision, got {self.kind!r}")


@dataclass
class Status(Message):
    """Health and diagnostics of a node or device: a state word plus numeric counters."""

    TYPE: ClassVar[str] = "handflow.Status"
    state: str = "ok"
    counters: dict[str, float] = field(default_factory=dict)
    text: str = ""


EVENT_KINDS = ("restart", "crash_loop", "gap", "dropped", "outage", "recovered")


@dataclass
class RuntimeEvent(Message):
    """Something the runtime noticed, published on ``handflow/<graph>/_runtime/events`` and recorded.

    ``kind``: ``restart`` (a node process was restarted), ``crash_loop`` (restarts given up),
    ``gap`` (``count`` messages missed on ``topic``), ``dropped`` (``count`` payloads on ``topic``
    failed validation), ``outage`` / ``recovered`` (a remote peer left / came back).
    See docs/monitoring.md.
    """

    TYPE: ClassVar[str] = "handflow.RuntimeEvent"
    kind: str = "restart"
    node: str = ""
    topic: str = ""
    count: int = 0
    detail: str = ""

    def _check_shapes(self) -> None:
        if self.kind not in EVENT_KINDS:
            raise MessageError(f"kind must be one of {', '.join(EVENT_KINDS)}, got {self.kind!r}")


# --------------------------------------------------------------------------------------------
# Codec
# --------------------------------------------------------------------------------------------
def message_types() -> dict[str, type[Message]]:
    """All known message types by ``TYPE`` name."""
    return dict(_REGISTRY)


def encode(msg: Message) -> bytes:
    """Compact JSON bytes of a message (wire and recording format)."""
    return json.dumps(msg.to_dict(), separators=(",", ":"), allow_nan=False).encode()


def decode(data: bytes | bytearray | memoryview) -> Message:
    """Inverse of :func:`encode`; raises :class:`MessageError` on unknown type or broken bytes."""
    try:
        d = json.loads(bytes(data))
        cls = _REGISTRY[d["type"]]
    except (ValueError, KeyError, TypeError) as exc:
        raise MessageError(f"cannot decode message: {exc}") from exc
    return cls.from_dict(d)


_JSON_TYPES = {"int": "integer", "float": "number", "str": "string", "bool": "boolean"}


def json_schema(cls: type[Message]) -> dict[str, Any]:
    """JSON schema of a message type, for MCAP channels (Foxglove reads JSON-schema channels)."""
    props: dict[str, Any] = {
        "type": {"type": "string"},
        "header": {
            "type": "object",
            "properties": {"source": {"type": "string"}, "seq": {"type": "integer"}, "stamp_ns": {"type": "integer"}},
        },
    }
    for f in dataclasses.fields(cls):
        if f.name == "header":
            continue
        meta = f.metadata
        tname = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", str(f.type))
        if meta.get("array"):
            item: dict[str, Any] = {
                "type": "boolean"
                if meta["array"] == "bool"
                else "integer"
                if meta["array"].startswith("int")
                else "number"
            }
            for _ in range(meta["ndim"]):
                item = {"type": "array", "items": item}
            props[f.name] = item
        elif tname == "bytes":
            props[f.name] = {"type": "string", "contentEncoding": "base64"}
        elif tname.startswith("list"):
            props[f.name] = {"type": "array", "items": {"type": "integer" if "int" in tname else "string"}}
        elif tname.startswith("dict"):
            props[f.name] = {"type": "object", "additionalProperties": {"type": "number"}}
        else:
            base = tname.split("|")[0].strip()
            props[f.name] = {"type": _JSON_TYPES.get(base, "string")}
    return {"title": cls.TYPE, "type": "object", "properties": props}
