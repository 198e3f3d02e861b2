"""Live view of a running graph: topics, rates, latency, sequence gaps, last values, node health.

docs/architecture.md ("Sequence gaps are counted and visible in the monitor").
:class:`Monitor` subscribes to ``handflow/<graph>/**`` of each graph it watches and keeps, per topic, a
sliding window of arrival times and end-to-end latencies (arrival wall clock − header
``stamp_ns``), the sequence gaps (a jump from seq n to n+k counts k−1 lost messages; a seq that goes
*back* — a replay loop or a fresh graph — restarts the count without a gap; the runner keeps
numbering across node restarts, so a restart is not a gap) and the last payload (decoded only when
a snapshot is taken).  Node health comes from the ``_health`` heartbeats: alive if one arrived
within :data:`ALIVE_S`; restarts are seen as a change of the heartbeat's pid.  Payloads a node dropped
(``dropped`` :class:`RuntimeEvent` on ``_runtime/events``, docs/robustness.md) are added to the
``dropped`` count of the topic they arrived on.
"""

from __future__ import annotations

import re
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import keys, wire
from ..messages import Array, Message, MessageError, RuntimeEvent, Status
from ..network.local_transport import PATH_NAMES
from ..network.shm import via_shm

ALIVE_S = 2.0  # a node is alive if its last heartbeat is younger than this
WINDOW_S = 5.0  # rate and latency are computed over this sliding window


@dataclass
class TopicStats:
    key: str
    type_name: str = ""
    count: int = 0
    gaps: int = 0
    dropped: int = 0
    last_seq: int = 0
    last_data: tuple[bytes, bytes | None] | None = None  # payload and attachment
    shm: bool = False  # the last payload arrived through shared memory (docs/shared_memory.md)
    arrivals: deque = field(default_factory=deque)  # (monotonic s, latency ns)

    def note(self, now_m: float, latency_ns: int | None, seq: int, window_s: float) -> None:
        self.count += 1
        if self.last_seq and seq > self.last_seq + 1:
            self.gaps += seq - self.last_seq - 1
        self.last_seq = seq
        self.arrivals.append((now_m, latency_ns))
        while self.arrivals and self.arrivals[0][0] < now_m - window_s:
            self.arrivals.popleft()

    def _arrivals(self) -> list[tuple[float, int | None]]:
        """The arrivals now: copied in one step (the transport's thread appends to the deque while
        a snapshot reads it)."""
        return list(self.arrivals)

    def rate_hz(self) -> float:
        arrivals = self._arrivals()
        if len(arrivals) < 2:
            return 0.0
        span = arrivals[-1][0] - arrivals[0][0]
        return (len(arrivals) - 1) / span if span > 0 else 0.0

    def latency_ms(self) -> float | None:
        known = [lat for _, lat in self._arrivals() if lat is not None]
        return float(np.median(known)) / 1e6 if known else None


@dataclass
class NodeHealth:
    graph: str
    id: str
    last_seen: float = 0.0  # monotonic s
    pid: int | None = None
    restarts: int = 0
    counters: dict[str, float] = field(default_factory=dict)


def summarize(msg: Message, max_values: int = 4) -> str:
    """A one-line summary of a message's payload for the table."""

    def arr(a: np.ndarray) -> str:
        flat = np.asarray(a).reshape(-1)
        head = ", ".join(f"{v:.3g}" if isinstance(v, float) else str(v) for v in flat[:max_values].tolist())
        return f"[{head}{', …' if flat.size > max_values else ''}] ({flat.size})"

    if isinstance(msg, Array):
        return arr(msg.data)
    if isinstance(msg, Status):
        return f"{msg.state} {msg.text}".strip()
    parts = []
    for name, value in vars(msg).items():
        if name == "header":
            continue
        if isinstance(value, np.ndarray):
            parts.append(f"{name}={arr(value)}")
        elif isinstance(value, bytes):
            parts.append(f"{name}=<{len(value)} bytes>")
        elif isinstance(value, list):
            parts.append(f"{name}=[{len(value)}]")
        else:
            parts.append(f"{name}={value!r}")
    return " ".join(parts)[:120]


_PID = re.compile(r"pid (\d+)")


class Monitor:
    """Collects live statistics of one graph, several (a list of names) or all graphs (None) on a Zenoh session."""

    def __init__(self, session: Any, graph: str | list[str] | None = None, window_s: float = WINDOW_S) -> None:
        self.window_s = window_s
        self.topics: dict[str, TopicStats] = {}
        self.nodes: dict[tuple[str, str], NodeHealth] = {}
        self._lock = threading.Lock()
        graphs = [graph] if isinstance(graph, str) else graph or ["*"]
        self._subs = [session.declare_subscriber(f"{keys.PREFIX}/{g}/**", self._on_sample) for g in graphs]

    def _on_sample(self, sample: Any) -> None:
        now_wall, now_m = time.time_ns(), time.monotonic()
        key = str(sample.key_expr)
        parts = keys.split_key(key)
        if parts is None or parts[2] == "_progress":
            return  # the lock-step clock and progress reports are runtime traffic, not data
        data, shm = wire.sample_parts(sample), via_shm(sample.payload)
        if parts[2] == "_health":
            self._on_health(parts[0], parts[1], data, now_m)
            return
        if (parts[1], parts[2]) == ("_runtime", "events"):
            self._on_event(data)
        try:
            hdr = wire.peek(*data)
        except MessageError:
            return
        with self._lock:
            stats = self.topics.get(key)
            if stats is None:
                stats = self.topics[key] = TopicStats(key, hdr.type_name)
            latency = now_wall - hdr.stamp_ns if hdr.stamp_ns else None  # Text carries no stamp
            stats.note(now_m, latency, hdr.seq, self.window_s)
            stats.last_data = data
            stats.shm = shm

    def _on_event(self, data: tuple[bytes, bytes | None]) -> None:
        try:
            event = wire.unpack(*data)
        except MessageError:
            return
        if isinstance(event, RuntimeEvent) and event.kind == "dropped":
            with self._lock:
                stats = self.topics.get(event.topic)
                if stats is None:
                    stats = self.topics[event.topic] = TopicStats(event.topic)
                stats.dropped += event.count

    def _on_health(self, graph: str, node: str, data: tuple[bytes, bytes | None], now_m: float) -> None:
        try:
            status = wire.unpack(*data)
        except MessageError:
            return
        m = _PID.search(getattr(status, "text", ""))
        pid = int(m.group(1)) if m else None
        with self._lock:
            h = self.nodes.get((graph, node))
            if h is None:
                h = self.nodes[(graph, node)] = NodeHealth(graph, node)
            elif pid is not None and h.pid is not None and pid != h.pid:
                h.restarts += 1
            h.pid = pid if pid is not None else h.pid
            h.last_seen = now_m
            h.counters = dict(getattr(status, "counters", {}))

    def snapshot(self) -> dict[str, Any]:
        """``{"topics": [{"topic", "rate_hz", "latency_ms", "gaps", ...}], "nodes": [{"id", "alive", ...}]}``."""
        now_m = time.monotonic()
        with self._lock:
            topics = list(self.topics.values())
            nodes = list(self.nodes.values())
            lasts = {t.key: t.last_data for t in topics}
            paths = {t.key: self._path(t.key) for t in topics}
        out_topics = []
        for t in sorted(topics, key=lambda t: t.key):
            try:
                last = summarize(wire.unpack(*lasts[t.key])) if lasts[t.key] else "-"
            except MessageError as exc:
                last = f"(undecodable: {exc})"
            lat = t.latency_ms()
            out_topics.append(
                {
                    "topic": t.key,
                    "type": t.type_name,
                    "rate_hz": round(t.rate_hz(), 2),
                    "latency_ms": None if lat is None else round(lat, 3),
                    "gaps": t.gaps,
                    "dropped": t.dropped,
                    "count": t.count,
                    "shm": t.shm,
                    "path": paths[t.key],
                    "last": last,
                }
            )
        out_nodes = []
        for h in sorted(nodes, key=lambda h: (h.graph, h.id)):
            c = h.counters
            out_nodes.append(
                {
                    "id": h.id,
                    "graph": h.graph,
                    "alive": now_m - h.last_seen < ALIVE_S,
                    "last_heartbeat_s": round(now_m - h.last_seen, 2),
                    "pid": h.pid,
                    "restarts_seen": h.restarts,
                    "dropped": int(sum(v for k, v in c.items() if k.startswith("dropped."))),
                    "input_gaps": int(sum(v for k, v in c.items() if k.startswith("gaps."))),
                    "handled": int(sum(v for k, v in c.items() if k.startswith("handled."))),
                    "published": int(sum(v for k, v in c.items() if k.startswith("published."))),
                }
            )
        return {"topics": out_topics, "nodes": out_nodes}

    def _path(self, key: str) -> str:
        """How the topic's last message left its node (its heartbeat's ``path.<port>``): ``iceoryx2``,
        ``zenoh``, both, or ``-`` when unknown (docs/shared_memory.md)."""
        graph, node, port = keys.split_key(key) or ("", "", "")
        health = self.nodes.get((graph, node))
        return PATH_NAMES.get(int(health.counters.get(f"path.{port}", 0)), "-") if health else "-"

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()


def render(
    snapshot: dict[str, Any], title: str = "handflow monitor", graph: str | None = None, width: int | None = None
) -> Any:
    """A rich renderable (two tables) of a snapshot, one line per topic and node within ``width``
    characters (None: every column, docs/monitoring.md); topics of ``graph`` are shown as ``node/port``."""
    from rich.console import Group
    from rich.text import Text

    from .fit import Column, fitted_table

    def column(header, short, cells, priority, justify="left", flexible=False):
        texts = [c if isinstance(c, Text) else Text(str(c)) for c in cells]
        return Column(header, short, texts, priority, justify, flexible)

    ts = snapshot["topics"]
    lost = [Text(f"{t['gaps']}/{t['dropped']}", style="red" if t["gaps"] or t["dropped"] else "") for t in ts]
    topics = [
        column(
            "topic",
            "topic",
            [t["topic"].removeprefix(f"{keys.PREFIX}/{graph}/") if graph else t["topic"] for t in ts],
            0,
        ),
        column("type", "type", [t["type"].removeprefix("handflow.") for t in ts], 6),
        column("rate Hz", "Hz", [f"{t['rate_hz']:.1f}" for t in ts], 1, "right"),
        column(
            "latency ms", "ms", ["-" if t["latency_ms"] is None else f"{t['latency_ms']:.2f}" for t in ts], 2, "right"
        ),
        column("gaps/dropped", "lost", lost, 3, "right"),
        column("count", "n", [t["count"] for t in ts], 5, "right"),
        column("shm", "shm", ["yes" if t["shm"] else "-" for t in ts], 7),
        column("path", "path", [t["path"] for t in ts], 8),
        column("last value", "last", [t["last"] for t in ts], 4, flexible=True),
    ]
    ns = snapshot["nodes"]
    alive = [
        Text("yes", style="green") if n["alive"] else Text(f"no ({n['last_heartbeat_s']:.0f}s)", style="red")
        for n in ns
    ]
    nodes = [
        column("node", "node", [n["id"] for n in ns], 0),
        column("alive", "alive", alive, 1),
        column("pid", "pid", [n["pid"] for n in ns], 7, "right"),
        column("restarts seen", "restarts", [n["restarts_seen"] for n in ns], 2, "right"),
        column("dropped", "dropped", [n["dropped"] for n in ns], 3, "right"),
        column("input gaps", "gaps", [n["input_gaps"] for n in ns], 4, "right"),
        column("handled", "handled", [n["handled"] for n in ns], 5, "right"),
        column("published", "published", [n["published"] for n in ns], 6, "right"),
    ]
    if graph is None:  # several graphs: say which one each node belongs to
        nodes.insert(0, column("graph", "graph", [n["graph"] for n in ns], 1))
    return Group(fitted_table(title, topics, width), fitted_table("nodes", nodes, width))
