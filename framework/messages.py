"""Typed message classes and their JSON dialect (docs/pipelines.md).

Every message carries a :class:`Header` (source node, sequence number, ``stamp_ns``).  Payloads are
plain dataclasses whose array fields are numpy arrays.  On the wire and in recordings they travel as
ROS 2 CDR (:mod:`handflow.framework.wire`, docs/ros2.md); :func:`encode` / :func:`decode` are the
self-describing JSON dialect (``{"type": ..., "header": ..., <fields>}``) still read from JSON
peers and older recordings.

Validation (:meth:`Message.check`) rejects NaN/inf and wrongly shaped payloads; the publisher calls
it and names the node and port in the error.  :func:`decode` is hardened for payloads from outside the
process (docs/robustness.md): every field is checked against its declared type (JSON kind, int64
range, array dtype and dimensions, finite floats) and the decoded message passes :meth:`Message.check`,
so any payload either decodes to a valid message or raises :class:`MessageError` — nothing else.
"""

from __future__ import annotations

import base64
import binascii
import dataclasses
import json
import math
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
        for name in _finite_scalar_fields(type(self)):
            value = getattr(self, name)
            values = value.values() if isinstance(value, dict) else (value,)
            if not all(math.isfinite(v) for v in values):
                raise MessageError(f"field '{name}' holds NaN/inf")
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
            if _annotation(f) == "bytes":  # bytes, or a uint8 buffer from ``Context.allocate``
                value = base64.b64encode(value).decode("ascii")
            elif isinstance(value, np.ndarray):
                value = value.tolist()
            out[f.name] = value
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Message:
        """Build a message from decoded JSON, checking every field's kind (raises :class:`MessageError`)."""
        kwargs = {}
        for f in dataclasses.fields(cls):
            if f.name == "header" or f.name not in d:
                continue
            if f.metadata.get("array"):
                kwargs[f.name] = _wire_array(f.name, d[f.name], f.metadata)
            else:
                kwargs[f.name] = _wire_value(f.name, d[f.name], _annotation(f))
        try:
            msg = cls(**kwargs)
        except (TypeError, ValueError, OverflowError) as exc:  # a subclass's own __post_init__ rules
            raise MessageError(f"invalid {cls.TYPE}: {exc}") from None
        msg.header = _wire_header(d.get("header", {}))
        return msg


def _array_fields(cls: type) -> list[dataclasses.Field]:
    cached = cls.__dict__.get("_array_fields_cache")
    if cached is None:
        cached = [f for f in dataclasses.fields(cls) if f.metadata.get("array")]
        cls._array_fields_cache = cached
    return cached


def _annotation(f: dataclasses.Field) -> str:
    return f.type if isinstance(f.type, str) else getattr(f.type, "__name__", str(f.type))


def _finite_scalar_fields(cls: type) -> list[str]:
    cached = cls.__dict__.get("_finite_scalars_cache")
    if cached is None:
        cached = [f.name for f in dataclasses.fields(cls) if _annotation(f) in ("float", "dict[str, float]")]
        cls._finite_scalars_cache = cached
    return cached


# --------------------------------------------------------------------------------------------
# Checked conversion of wire values (JSON) to field values
# --------------------------------------------------------------------------------------------
INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1


def _wire_int(name: str, value: Any) -> int:
    if type(value) is not int or not INT64_MIN <= value <= INT64_MAX:
        raise MessageError(f"field '{name}' must be an int64 integer, got {_brief(value)}")
    return value


def _wire_float(name: str, value: Any) -> float:
    if type(value) not in (int, float):
        raise MessageError(f"field '{name}' must be a number, got {_brief(value)}")
    out = float(value) if abs(value) < 2**1023 else math.inf  # an int too large for a float
    if not math.isfinite(out):
        raise MessageError(f"field '{name}' must be finite, got {_brief(value)}")
    return out


def _wire_str(name: str, value: Any) -> str:
    if type(value) is not str:
        raise MessageError(f"field '{name}' must be a string, got {_brief(value)}")
    if not value.isascii():
        try:
            value.encode()
        except UnicodeEncodeError:
            raise MessageError(f"field '{name}' holds a lone surrogate (not Unicode text)") from None
    return value


def _wire_bool(name: str, value: Any) -> bool:
    if type(value) is not bool:
        raise MessageError(f"field '{name}' must be true or false, got {_brief(value)}")
    return value


def _wire_list(name: str, value: Any, item: Any) -> list:
    if type(value) is not list:
        raise MessageError(f"field '{name}' must be a list, got {_brief(value)}")
    return [item(f"{name}[{i}]", v) for i, v in enumerate(value)]


def _wire_bytes(name: str, value: Any) -> bytes:
    try:
        return base64.b64decode(_wire_str(name, value), validate=True)
    except (binascii.Error, ValueError) as exc:
        raise MessageError(f"field '{name}' must be base64 text: {exc}") from None


def _wire_float_dict(name: str, value: Any) -> dict[str, float]:
    if type(value) is not dict:
        raise MessageError(f"field '{name}' must be an object of numbers, got {_brief(value)}")
    return {k: _wire_float(f"{name}.{k}", v) for k, v in value.items()}


_WIRE_VALUE = {
    "str": _wire_str,
    "int": _wire_int,
    "float": _wire_float,
    "bool": _wire_bool,
    "bytes": _wire_bytes,
    "list[str]": lambda name, v: _wire_list(name, v, _wire_str),
    "list[int]": lambda name, v: _wire_list(name, v, _wire_int),
    "dict[str, float]": _wire_float_dict,
    "int | None": lambda name, v: None if v is None else _wire_int(name, v),
    "float | None": lambda name, v: None if v is None else _wire_float(name, v),
    "str | None": lambda name, v: None if v is None else _wire_str(name, v),
}


def _wire_value(name: str, value: Any, annotation: str) -> Any:
    """A scalar/list/dict field from JSON, checked against its annotation (others pass unchanged)."""
    convert = _WIRE_VALUE.get(annotation)
    return value if convert is None else convert(name, value)


# array dtype kind → JSON element kinds numpy may infer for it ("b" bool, "i"/"u" int, "f" float)
_ARRAY_SOURCE_KINDS = {"f": "biuf", "i": "iu", "u": "iu", "b": "b"}


def _wire_array(name: str, value: Any, meta: dict[str, Any]) -> np.ndarray:
    """A (nested) JSON list as a numpy array of the field's dtype and dimensions."""
    dtype = np.dtype(meta["array"])
    if type(value) is not list:
        raise MessageError(f"field '{name}' must be a list, got {_brief(value)}")
    try:
        arr = np.asarray(value)
    except (ValueError, TypeError, OverflowError, RecursionError) as exc:
        raise MessageError(f"field '{name}' is not a regular array: {str(exc)[:120]}") from None
    ndim, cols = meta["ndim"], meta["cols"]
    if arr.size == 0:
        return np.zeros((0,) * ndim if cols is None else (0, cols), dtype=dtype)
    if arr.dtype.kind not in _ARRAY_SOURCE_KINDS[dtype.kind]:
        raise MessageError(f"field '{name}' must hold {dtype.name} values, got {arr.dtype.name} elements")
    if arr.ndim != ndim:
        raise MessageError(f"field '{name}' must have {ndim} dimension(s), got shape {arr.shape}")
    if dtype.kind in "iu":
        info = np.iinfo(dtype)
        if arr.min() < info.min or arr.max() > info.max:
            raise MessageError(f"field '{name}' holds values outside the {dtype.name} range")
    with np.errstate(over="ignore"):
        return arr.astype(dtype)


def _wire_header(value: Any) -> Header:
    if type(value) is not dict:
        raise MessageError(f"header must be an object, got {_brief(value)}")
    h = Header(
        _wire_str("header.source", value.get("source", "")),
        _wire_int("header.seq", value.get("seq", 0)),
        _wire_int("header.stamp_ns", value.get("stamp_ns", 0)),
    )
    if h.seq < 0 or h.stamp_ns < 0:
        raise MessageError(f"header.seq and header.stamp_ns must not be negative, got {h.seq}, {h.stamp_ns}")
    return h


def _brief(value: Any) -> str:
    text = repr(value)
    return f"{type(value).__name__} {text[:40]}{'…' if len(text) > 40 else ''}"


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
        if any(n < 0 for n in self.shape) or math.prod(self.shape) != self.data.size:
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
        points = d.get("points", [])
        if type(points) is list:
            d = dict(d, points=[[np.nan, np.nan] if p is None else p for p in points])
        return super().from_dict(d)


IMAGE_ENCODINGS = {"mono8": 1, "rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mono16": 2}  # bytes per pixel


@dataclass
class Image(Message):
    """Raw image, field names as Foxglove's ``foxglove.RawImage`` (data base64 in JSON).

    ``data`` is ``bytes``, or a flat ``uint8`` array from ``ctx.allocate`` filled in place (docs/shared_memory.md).
    """

    TYPE: ClassVar[str] = "handflow.Image"
    width: int = 0
    height: int = 0
    encoding: str = "rgb8"
    step: int = 0
    data: bytes = b""
    frame_id: str = "camera"

    def _check_shapes(self) -> None:
        if min(self.width, self.height, self.step) < 0:
            raise MessageError(
                f"width, height and step must not be negative, got {self.width}, {self.height}, {self.step}"
            )
        pixel = IMAGE_ENCODINGS.get(self.encoding)
        if pixel is not None and self.step < self.width * pixel:
            raise MessageError(
                f"{self.encoding} rows of {self.width} pixels need a step ≥ {self.width * pixel}, got {self.step}"
            )
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
        channels = IMAGE_ENCODINGS.get(self.encoding) or self.step // max(self.width, 1)
        rows = np.frombuffer(self.data, dtype=np.uint8).reshape(self.height, self.step)
        arr = rows[:, : self.width * channels].reshape(self.height, self.width, channels)
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


@dataclass
class CompressedImage(Message):
    """Compressed camera image (``format`` ``jpeg`` or ``png``, as ``sensor_msgs/CompressedImage``)."""

    TYPE: ClassVar[str] = "handflow.CompressedImage"
    format: str = "jpeg"
    data: bytes = b""
    frame_id: str = "camera"


def _unit_quaternions(q: np.ndarray) -> bool:
    """Every row a unit quaternion within 1e-3 (huge values fail without an overflow warning)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return bool(np.all(np.abs(np.einsum("ij,ij->i", q, q) - 1.0) <= 2e-3))


@dataclass
class Transforms(Message):
    """Rigid transforms ``parents[i]`` → ``children[i]`` at the header's stamp (``tf2_msgs/TFMessage``).

    ``translations`` (n, 3) in metres; ``rotations`` (n, 4) unit quaternions ``x, y, z, w``: the
    pose of the child frame in the parent frame (docs/foxglove.md).
    """

    TYPE: ClassVar[str] = "handflow.Transforms"
    parents: list[str] = field(default_factory=list)
    children: list[str] = field(default_factory=list)
    translations: np.ndarray = _array("float64", 2, cols=3)
    rotations: np.ndarray = _array("float64", 2, cols=4)

    def _check_shapes(self) -> None:
        n = len(self.children)
        if not len(self.parents) == n == self.translations.shape[0] == self.rotations.shape[0]:
            raise MessageError("parents, children, translations and rotations need one entry per transform")
        if not _unit_quaternions(self.rotations):
            raise MessageError("rotations must be unit quaternions (x, y, z, w)")


MARKER_KINDS = {"arrow": 0, "cube": 1, "sphere": 2, "cylinder": 3, "text": 9}
"""Marker shapes handflow publishes, with their ``visualization_msgs/Marker`` type codes."""


@dataclass
class Markers(Message):
    """Shapes and texts to draw in 3D, one entry per marker (``visualization_msgs/MarkerArray``).

    ``kinds`` from :data:`MARKER_KINDS`; ``positions`` (n, 3) and ``orientations`` (n, 4, quaternion
    ``x, y, z, w``) in ``frame_ids``; ``scales`` (n, 3) the size in metres (a text's height is
    ``scales[:, 2]``); ``colours`` (n, 4) RGBA in 0..1; ``texts`` the strings of text markers.
    A marker replaces the earlier one of the same ``namespaces[i]`` and ``ids[i]``.
    """

    TYPE: ClassVar[str] = "handflow.Markers"
    kinds: list[str] = field(default_factory=list)
    frame_ids: list[str] = field(default_factory=list)
    namespaces: list[str] = field(default_factory=list)
    ids: np.ndarray = _array("int32")
    positions: np.ndarray = _array("float64", 2, cols=3)
    orientations: np.ndarray = _array("float64", 2, cols=4)
    scales: np.ndarray = _array("float64", 2, cols=3)
    colours: np.ndarray = _array("float32", 2, cols=4)
    texts: list[str] = field(default_factory=list)

    def _check_shapes(self) -> None:
        n = len(self.kinds)
        sizes = (len(self.frame_ids), len(self.namespaces), self.ids.size, len(self.texts))
        arrays = (self.positions, self.orientations, self.scales, self.colours)
        if any(k != n for k in sizes) or any(a.shape[0] != n for a in arrays):
            raise MessageError("every marker field needs one entry per marker")
        unknown = sorted(set(self.kinds) - set(MARKER_KINDS))
        if unknown:
            raise MessageError(f"marker kinds {unknown} are not among {', '.join(MARKER_KINDS)}")
        if not _unit_quaternions(self.orientations):
            raise MessageError("orientations must be unit quaternions (x, y, z, w)")


@dataclass
class Text(Message):
    """A text document, e.g. a robot description (URDF) for viewers (``std_msgs/String``)."""

    TYPE: ClassVar[str] = "handflow.Text"
    data: str = ""


EVENT_KINDS = ("restart", "crash_loop", "gap", "dropped", "outage", "recovered", "reload")


@dataclass
class RuntimeEvent(Message):
    """Something the runtime noticed, published on ``handflow/<graph>/_runtime/events`` and recorded.

    ``kind``: ``restart`` (a node process was restarted), ``crash_loop`` (restarts given up),
    ``gap`` (``count`` messages missed on ``topic``), ``dropped`` (``count`` payloads on ``topic``
    failed validation), ``outage`` / ``recovered`` (a remote peer left / came back), ``reload`` (``handflow
    run --watch`` restarted, started or stopped a node process after an edit; ``detail``: which and why).
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


@dataclass
class ParamChange(Message):
    """A parameter change a running node accepted, on ``handflow/<graph>/_params/changes`` and recorded.

    ``value`` and ``previous`` are JSON texts; the header's source is the node, its stamp the one of the
    first input (or tick) the node handled with the new value, so lock-step replay can apply it at the
    same point (docs/tuning.md).  ``restart``: the node was restarted to take it.
    """

    TYPE: ClassVar[str] = "handflow.ParamChange"
    node: str = ""
    key: str = ""
    value: str = "null"
    previous: str = "null"
    restart: bool = False


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
    """Inverse of :func:`encode`: a valid, checked message, or :class:`MessageError` saying what is wrong.

    Safe on any bytes from the wire (docs/robustness.md): JSON's ``NaN``/``Infinity`` literals,
    wrong field kinds, out-of-range integers, ragged arrays and failed :meth:`Message.check` rules
    are all rejected with :class:`MessageError`.
    """
    try:
        d = json.loads(bytes(data), parse_constant=_no_constant)
    except (ValueError, TypeError, RecursionError) as exc:  # UnicodeDecodeError is a ValueError
        raise MessageError(f"cannot decode message: {str(exc)[:200]}") from None
    if type(d) is not dict:
        raise MessageError(f"cannot decode message: expected a JSON object, got {type(d).__name__}")
    type_name = d.get("type")
    cls = _REGISTRY.get(type_name) if type(type_name) is str else None
    if cls is None:
        raise MessageError(f"cannot decode message: unknown message type {_brief(type_name)}")
    msg = cls.from_dict(d)
    try:
        msg.check()
    except (TypeError, ValueError, OverflowError, IndexError) as exc:  # incl. check rules of plugin-defined types
        raise MessageError(f"invalid {cls.TYPE}: {exc}") from None
    return msg


def _no_constant(name: str) -> float:
    raise ValueError(f"{name} is not allowed (messages carry finite numbers)")


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
