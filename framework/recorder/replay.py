"""Replay MCAP recordings into Zenoh: timed, or lock-step in virtual time.

- :class:`TimedReplayer` publishes the recorded CDR bytes (nothing re-encoded; records of the JSON
  dialect are converted, :meth:`RecordedMessage.wire`) with the original
  inter-message timing (``log_time`` deltas) divided by ``speed``, optionally looping.
- :class:`LockstepReplayer` drives a graph launched with ``--lockstep``: before each message it
  publishes the virtual time on ``handflow/<graph>/_clock`` (``{"t_ns": stamp}``) and waits until
  every node acknowledged it, then publishes the message and waits until the graph is quiet: for
  every edge ``source → (node, port)``, the node's ``handled[port]`` equals the source's
  ``published`` count (from the nodes' ``_progress`` reports; for replayed topics, the replayer's
  own count).  Each message and everything it triggers downstream is processed before the next
  is released, so outputs do not depend on the machine's load.
- :class:`GraphWatcher` follows the ``_health`` heartbeats and ``_progress`` reports; replay
  releases nothing before every node has sent a heartbeat (its subscriptions are declared then).

Keys are remapped from the recorded graph onto the target graph with :func:`remap_key`.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from .. import keys, wire
from ..files.mcap_reader import ReadReport, RecordedMessage, iter_recording
from ..graphs.model import Graph
from ..messages import MessageError

log = logging.getLogger("handflow.replay")


class ReplayError(RuntimeError):
    """Replay cannot go on (graph not up, a step that never settles); the text says why."""


def remap_key(key: str, graph: str | None) -> str:
    """``handflow/<recorded>/<node>/<port>`` → ``handflow/<graph>/<node>/<port>`` (unchanged if graph is None)."""
    parts = keys.split_key(key)
    if graph is None or parts is None:
        return key
    return keys.topic_key(graph, parts[1], parts[2])


def external_inputs(graph: Graph) -> set[str]:
    """``node/port`` sources the graph's nodes read but no node of the graph publishes."""
    return {
        src
        for rn in graph.nodes.values()
        for src in rn.spec.inputs.values()
        if src.partition("/")[0] not in graph.nodes
    }


@dataclass
class ReplayStats:
    published: Counter = field(default_factory=Counter)  # key → messages published
    loops: int = 0
    report: ReadReport | None = None

    @property
    def total(self) -> int:
        return sum(self.published.values())


# ----------------------------------------------------------------------------------------------
# Watching a graph
# ----------------------------------------------------------------------------------------------
class GraphWatcher:
    """Latest ``_health`` counters and ``_progress`` reports of a graph's nodes."""

    def __init__(self, session: zenoh.Session, graph_name: str) -> None:
        self.graph_name = graph_name
        self.health: dict[str, dict[str, float]] = {}
        self.beats: Counter = Counter()  # heartbeats received per node
        self.progress: dict[str, dict[str, Any]] = {}
        self.cond = threading.Condition()
        self._subs = [
            session.declare_subscriber(keys.topic_key(graph_name, "*", "_health"), self._on_health),
            session.declare_subscriber(keys.topic_key(graph_name, "*", "_progress"), self._on_progress),
        ]

    def _on_health(self, sample: Any) -> None:
        try:
            status = wire.unpack(*wire.sample_parts(sample))
        except MessageError:
            return
        with self.cond:
            self.health[status.header.source] = dict(getattr(status, "counters", {}))
            self.beats[status.header.source] += 1
            self.cond.notify_all()

    def _on_progress(self, sample: Any) -> None:
        parts = keys.split_key(str(sample.key_expr))
        if parts is None:
            return
        body = json.loads(sample.payload.to_bytes())
        with self.cond:
            old = self.progress.get(parts[1], {"handled": {}, "published": {}, "clock": None})
            # reports of one node arrive in order, but keep counters monotonic whatever happens
            merged = {k: {p: max(n, old[k].get(p, 0)) for p, n in body[k].items()} for k in ("handled", "published")}
            clocks = [c for c in (old["clock"], body.get("clock")) if c is not None]
            merged["clock"] = max(clocks) if clocks else None
            self.progress[parts[1]] = merged
            self.cond.notify_all()

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float, poll: Callable[[], None] | None = None) -> bool:
        """Wait until ``predicate()`` (evaluated under the watcher's lock) holds; False on timeout."""
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while not predicate():
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self.cond.wait(min(left, 0.1))
                if poll is not None:
                    poll()
        return True

    def wait_alive(
        self,
        node_ids: Iterable[str],
        timeout_s: float,
        poll: Callable[[], None] | None = None,
        stop: threading.Event | None = None,
    ) -> None:
        """Block until every node has sent a heartbeat, or ``stop`` is set; :class:`ReplayError` names the
        missing ones."""
        ids = set(node_ids)
        stopped = stop.is_set if stop is not None else lambda: False
        if not self.wait_for(lambda: ids <= set(self.health) or stopped(), timeout_s, poll):
            missing = sorted(ids - set(self.health))
            raise ReplayError(
                f"node(s) {', '.join(missing)} of graph '{self.graph_name}' sent no heartbeat within "
                f"{timeout_s:.0f}s; check their logs above (or raise --ready-timeout)"
            )

    def forget(self) -> None:
        """Drop what the nodes reported (their processes are being started afresh)."""
        with self.cond:
            self.health.clear()
            self.progress.clear()

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()


def wait_matching(publishers: Iterable[Any], timeout_s: float) -> bool:
    """Wait until every publisher has a matching subscriber (Zenoh routes are in place)."""
    deadline = time.monotonic() + timeout_s
    pubs = list(publishers)
    while time.monotonic() < deadline:
        if all(p.matching_status.matching for p in pubs):
            return True
        time.sleep(0.01)
    return False


class _Publishers:
    """One reliable (blocking) publisher per key, declared on first use.

    A new publisher first waits up to ``match_timeout_s`` for a matching subscriber, so the first
    messages are not published before the routes to a just-started graph exist.
    """

    def __init__(self, session: zenoh.Session, match_timeout_s: float = 0.0) -> None:
        self.session = session
        self.match_timeout_s = match_timeout_s
        self.by_key: dict[str, Any] = {}

    def __getitem__(self, key: str) -> Any:
        pub = self.by_key.get(key)
        if pub is None:
            pub = self.by_key[key] = self.session.declare_publisher(
                key, congestion_control=zenoh.CongestionControl.BLOCK
            )
            if self.match_timeout_s and not wait_matching([pub], self.match_timeout_s):
                log.warning("no subscriber for %s after %.1fs; publishing anyway", key, self.match_timeout_s)
        return pub

    def prepare(self, keys: Iterable[str], timeout_s: float) -> None:
        """Declare publishers up front and wait (once, for all) until they have subscribers."""
        pubs = [
            self.session.declare_publisher(k, congestion_control=zenoh.CongestionControl.BLOCK)
            for k in keys
            if k not in self.by_key
        ]
        self.by_key.update({str(p.key_expr): p for p in pubs})
        if pubs and not wait_matching(pubs, timeout_s):
            missing = [str(p.key_expr) for p in pubs if not p.matching_status.matching]
            log.warning("no subscriber yet for %s after %.1fs; replaying anyway", ", ".join(missing), timeout_s)

    def close(self) -> None:
        for pub in self.by_key.values():
            pub.undeclare()


# ----------------------------------------------------------------------------------------------
# Selecting what to replay
# ----------------------------------------------------------------------------------------------
@dataclass
class ReplayPlan:
    """Which recorded topics to publish, under which keys."""

    path: Path
    topics: list[str] | None = None  # TopicFilter globs over the recorded topics
    target_graph: str | None = None  # remap onto this graph name
    only_sources: set[str] | None = None  # keep only these node/port sources (after remap)

    def messages(self, report: ReadReport | None = None) -> Iterator[tuple[str, RecordedMessage]]:
        """(target key, recorded message) in file order."""
        for rm in iter_recording(self.path, self.topics, report=report):
            key = remap_key(rm.topic, self.target_graph)
            if self.only_sources is not None:
                parts = keys.split_key(key)
                if parts is None or f"{parts[1]}/{parts[2]}" not in self.only_sources:
                    continue
            yield key, rm


# ----------------------------------------------------------------------------------------------
# Timed replay
# ----------------------------------------------------------------------------------------------
class TimedReplayer:
    """Publish a recording with its original timing scaled by ``speed`` (2.0 = twice as fast)."""

    def __init__(
        self,
        session: zenoh.Session,
        plan: ReplayPlan,
        *,
        speed: float = 1.0,
        loop: bool = False,
        stop: threading.Event | None = None,
        match_timeout_s: float = 0.0,
    ) -> None:
        if not speed > 0:
            raise ValueError(f"speed must be > 0, got {speed}")
        self.plan, self.speed, self.loop = plan, speed, loop
        self.stop = stop or threading.Event()
        self.pubs = _Publishers(session, match_timeout_s)

    def run(self) -> ReplayStats:
        stats = ReplayStats()
        while not self.stop.is_set():
            stats.report = ReadReport(self.plan.path)
            wall0 = log0 = None
            for key, rm in self.plan.messages(stats.report):
                if log0 is None:
                    wall0, log0 = time.monotonic(), rm.log_time_ns
                due = wall0 + (rm.log_time_ns - log0) / 1e9 / self.speed
                if self.stop.wait(max(0.0, due - time.monotonic())):
                    break
                payload, att = rm.wire()
                self.pubs[key].put(payload, attachment=att)
                stats.published[key] += 1
            stats.loops += 1
            if not self.loop or stats.report.messages == 0:
                break
        self.pubs.close()
        return stats


# ----------------------------------------------------------------------------------------------
# Lock-step replay
# ----------------------------------------------------------------------------------------------
class LockstepReplayer:
    """Feed a lock-step graph one message at a time in virtual time (see the module docstring)."""

    def __init__(
        self,
        session: zenoh.Session,
        graph: Graph,
        node_ids: Iterable[str],
        watcher: GraphWatcher,
        *,
        step_timeout_s: float = 10.0,
        stop: threading.Event | None = None,
        poll: Callable[[], None] | None = None,
    ) -> None:
        self.graph = graph
        self.node_ids = list(node_ids)
        self.watcher = watcher
        self.step_timeout_s = step_timeout_s
        self.stop = stop or threading.Event()
        self.poll = poll
        self.pubs = _Publishers(session, match_timeout_s=step_timeout_s)
        self.clock_pub = session.declare_publisher(
            keys.clock_key(graph.name), congestion_control=zenoh.CongestionControl.BLOCK
        )
        self.sent: Counter = Counter()  # node/port → messages the replayer published
        self.t_ns: int | None = None  # the virtual time published last
        self.edges = [(src, nid, port) for nid in self.node_ids for port, src in graph.nodes[nid].spec.inputs.items()]

    # -- conditions (evaluated under the watcher's lock) ------------------------------------
    def _published(self, source: str) -> int:
        node, _, port = source.partition("/")
        if node in self.graph.nodes:
            return int(self.watcher.progress.get(node, {}).get("published", {}).get(port, 0))
        return self.sent[source]

    def _unsettled(self) -> list[str]:
        out = []
        for src, nid, port in self.edges:
            handled = int(self.watcher.progress.get(nid, {}).get("handled", {}).get(port, 0))
            published = self._published(src)
            if handled != published:
                out.append(f"{src} → {nid}.{port}: published {published}, handled {handled}")
        return out

    def _clock_acked(self, t_ns: int) -> bool:
        clocks = [self.watcher.progress.get(n, {}).get("clock") for n in self.node_ids]
        return all(c is not None and c >= t_ns for c in clocks)  # a recording may start at stamp 0

    def _settle(self, what: str, extra: Callable[[], bool] = lambda: True) -> None:
        if not self.watcher.wait_for(lambda: extra() and not self._unsettled(), self.step_timeout_s, self.poll):
            with self.watcher.cond:
                detail = "; ".join(self._unsettled()) or "nodes did not acknowledge the clock"
            raise ReplayError(
                f"lock-step: the graph did not settle within {self.step_timeout_s:.0f}s after {what} "
                f"({detail}); a node may have crashed or dropped a message — see its log"
            )

    def advance_clock(self, t_ns: int) -> None:
        """Publish the virtual time and wait until every node ran its ticks up to it and all is processed."""
        payload = json.dumps({"t_ns": int(t_ns)})
        self.clock_pub.put(payload)
        deadline = time.monotonic() + self.step_timeout_s
        # a clock is idempotent, so re-send it while unacknowledged (covers routes still forming)
        while not self.watcher.wait_for(lambda: self._clock_acked(t_ns), 0.5, self.poll):
            if time.monotonic() > deadline or self.stop.is_set():
                break
            self.clock_pub.put(payload)
        self._settle(f"clock {t_ns}", lambda: self._clock_acked(t_ns))

    def published(self) -> dict[str, int]:
        """Topic key → messages each node output published since the node's (re)start: the last sequence
        number, as a graph started afresh numbers them from 1 (:meth:`..runtime.launcher.Launcher.reset`)."""
        with self.watcher.cond:
            return {
                keys.topic_key(self.graph.name, nid, port): int(n)
                for nid, report in self.watcher.progress.items()
                for port, n in report["published"].items()
            }

    def step(self, key: str, rm: RecordedMessage, stats: ReplayStats, changes: Any = None) -> None:
        """Release one message: the recorded changes due, the clock, the message; return once the graph is quiet."""
        stamp = rm.publish_time_ns
        if changes is not None:
            changes.before(stamp)
        if self.t_ns is None or stamp > self.t_ns:
            self.t_ns = stamp
            self.advance_clock(stamp)
        parts = keys.split_key(key)
        with self.watcher.cond:
            self.sent[f"{parts[1]}/{parts[2]}"] += 1
        payload, att = rm.wire()
        self.pubs[key].put(payload, attachment=att)
        stats.published[key] += 1
        self._settle(f"message #{stats.total} on {key}")

    def rewind(self, restart_graph: Callable[[], None], ready_timeout_s: float) -> None:
        """Back to the start: ``restart_graph()`` starts the graph's nodes afresh; the counters and the clock
        start over once every node has sent a heartbeat again (docs/recording.md, "Replay from Foxglove's
        playback bar")."""
        self.watcher.forget()
        restart_graph()
        self.watcher.wait_alive(self.node_ids, ready_timeout_s, self.poll)
        with self.watcher.cond:  # a late report of a stopped process must not count as a new one's
            self.watcher.progress.clear()
            self.sent.clear()
        self.t_ns = None

    def run(self, plan: ReplayPlan, changes: Any = None) -> ReplayStats:
        """Replay ``plan``; ``changes`` (:class:`.param_replay.RecordedChanges`) are applied before the
        first message stamped at or after each of them."""
        stats = ReplayStats(report=ReadReport(plan.path))
        for key, rm in plan.messages(stats.report):
            if self.stop.is_set():
                break
            self.step(key, rm, stats, changes)
        stats.loops = 1
        self.close()
        return stats

    def close(self) -> None:
        self.pubs.close()
        self.clock_pub.undeclare()
