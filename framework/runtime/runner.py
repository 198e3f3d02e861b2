"""One node process: runs a group of graph nodes (docs/architecture.md).

Started by the launcher as ``python -m handflow.framework.runtime.runner GRAPH --nodes a,b --hub ENDPOINT``.
Messages are handled directly in the Zenoh callback and ticks in the main loop, serialised by one
lock, so node code never runs concurrently with itself (no locks needed in plugins) and a message
costs no thread hand-off.  Each node publishes a ``_health`` heartbeat with its counters.

Sequence numbers and the last sequence seen per input survive a restart through a small state file
per node (written in place, so a ``kill -9`` loses nothing): a restarted node continues its
numbering and counts the messages it missed while down as gaps.

Robustness (docs/robustness.md): a payload that does not decode to a valid message of the input's
type, or that makes ``on_message`` raise :class:`MessageError`, is dropped, counted per input
(``dropped.<port>`` in the heartbeat), logged at a limited rate and reported as a ``dropped``
:class:`RuntimeEvent` on ``handflow/<graph>/_runtime/events``; the node keeps running.

Live parameters (docs/tuning.md): each node answers its launcher's parameter requests
(:mod:`.live_params`) on a session of its own and takes a new value through ``Node.on_params``
under the same lock.

Lock-step mode (``--lockstep``): no wall-clock ticks; the replayer publishes the virtual time on
``_clock``, nodes run the ticks due up to it and report their per-port counters on ``_progress``
after every event, so the replayer can release the next message only when the graph is quiet.
"""

from __future__ import annotations

import argparse
import faulthandler
import heapq
import json
import logging
import os
import queue
import signal
import sys
import threading
import time
import traceback
from pathlib import Path

import numpy as np

from .. import keys, wire
from ..graphs.model import Graph, ResolvedNode, load_graph
from ..messages import Header, Message, MessageError, Status
from ..network import sessions as transport
from ..network.shm import SharedPayloads
from ..plugin import Node
from ..security.credentials import read_credentials, usrpwd_settings
from . import forwarding, local_routes
from .drops import DropLedger
from .live_params import NodeParams, overrides_file
from .publish import allocate_output, check_publish
from .wakeup import wakeup_queue

log = logging.getLogger("handflow.runner")

HEARTBEAT_S = 0.5
ORPHAN_POLL_S = 0.2
ORPHAN_GRACE_S = 1.5
STOPPED = "stopped"  # the state of a node's last heartbeat, sent after everything it published
START_WAIT_S = 60.0  # without a start signal (no launcher), tick anyway after this long
SETTLE_QUIET_S = 0.2  # at a stop, inputs are still handled until none came for this long …
SETTLE_MAX_S = 1.0  # … or for at most this long (below ORPHAN_GRACE_S)
RESTART_SIGNAL = signal.SIGUSR2  # stop at once: the launcher restarts this process alone, its inputs keep flowing
_STATE_SLOTS = 128
EXPECTED_ERRORS = (OSError, ValueError, RuntimeError, ImportError)
"""Errors a node raises on purpose with a message saying what to do: logged without a traceback."""


class SetupError(Exception):
    """A node's ``setup`` raised ``cause``."""

    def __init__(self, node_id: str, cause: BaseException) -> None:
        self.node_id, self.cause = node_id, cause
        super().__init__(f"node '{node_id}' failed during setup: {cause}")


def seq_file(state_dir: Path, node_id: str) -> Path:
    """Where a node keeps its sequence numbers across restarts within a run (:class:`SeqState`)."""
    return Path(state_dir) / f"{node_id}.seq"


def node_state_files(state_dir: Path, node_id: str) -> list[Path]:
    """What a node keeps across restarts within a run: its sequence numbers and parameters set while running."""
    return [seq_file(state_dir, node_id), overrides_file(state_dir, node_id)]


def failure_file(state_dir: Path, node_ids: list[str]) -> Path:
    """Where a node process leaves why it failed, for the launcher's report (docs/reliability.md)."""
    return Path(state_dir) / f"failure-{','.join(node_ids)}.json"


class SeqState:
    """Persistent per-node counters: output sequence numbers and last input sequence per source."""

    def __init__(self, path: Path | None, keys: list[str]) -> None:
        self.index = {k: i for i, k in enumerate(keys[:_STATE_SLOTS])}
        self.resumed = False  # the node ran earlier in this run (a restart): its file existed
        if path is None:
            self.values = np.zeros(_STATE_SLOTS, dtype=np.int64)
        else:
            mode = "r+" if path.exists() and path.stat().st_size == _STATE_SLOTS * 8 else "w+"
            self.resumed = mode == "r+"
            self.values = np.memmap(path, dtype=np.int64, mode=mode, shape=(_STATE_SLOTS,))

    def get(self, key: str) -> int:
        return int(self.values[self.index[key]])

    def set(self, key: str, value: int) -> None:
        self.values[self.index[key]] = value


class NodeContext:
    """The runtime's :class:`handflow.framework.plugin.Context` for one node."""

    def __init__(self, runtime: GroupRuntime, rn: ResolvedNode, state: SeqState) -> None:
        self.node_id = rn.spec.id
        self.graph_name = runtime.graph.name
        self.log = logging.getLogger(f"handflow.node.{self.node_id}")
        self._rt = runtime
        self._outputs = rn.cls.output_types(rn.params)
        self._state = state
        self.restarted = state.resumed
        self._pubs = {
            port: runtime.output_port(keys.topic_key(self.graph_name, self.node_id, port), cls)
            for port, cls in self._outputs.items()
        }
        self.published = dict.fromkeys(self._outputs, 0)
        self.shared = dict.fromkeys(self._outputs, 0)  # published from shared memory
        self.paths = dict.fromkeys(self._outputs, 0)  # the paths of the last message (local_routes)
        self._received: tuple[Message, bytes, tuple] | None = None  # being handled: message, CDR body, snapshot

    def receiving(self, msg: Message | None, body: bytes | None = None) -> None:
        """The runtime hands ``msg`` (decoded from the CDR ``body``) to the node; ``None`` when done."""
        snap = forwarding.snapshot(msg) if msg is not None and body is not None and self._outputs else None
        self._received = None if snap is None else (msg, body, snap)

    def publish(self, port: str, msg: Message, stamp_ns: int | None = None) -> None:
        received = self._received
        forwarded = received is not None and msg is received[0] and forwarding.unchanged(msg, received[2])
        check_publish(self.node_id, self._outputs, port, msg, validated=forwarded)
        seq = self._state.get("out:" + port) + 1
        self._state.set("out:" + port, seq)
        msg.header = Header(self.node_id, seq, self.now_ns() if stamp_ns is None else int(stamp_ns))
        body = received[1] if forwarded else None
        self.paths[port], pooled = self._pubs[port].publish(msg, body, self._rt.shared.wrap)
        self.published[port] += 1
        self.shared[port] += pooled

    def allocate(self, port: str, nbytes: int) -> np.ndarray:
        if port not in self._pubs:
            return allocate_output(self.node_id, self._outputs, port, nbytes)  # raises, naming the ports
        return self._pubs[port].allocate(nbytes)

    def now_ns(self) -> int:
        return self._rt.now_ns()

    def resolve_path(self, path: str | Path) -> Path:
        p = Path(path).expanduser()
        return p if p.is_absolute() else (self._rt.graph.base_dir / p).resolve()

    def output_path(self, path: str | Path) -> Path:
        p = Path(path).expanduser().resolve()
        p.parent.mkdir(parents=True, exist_ok=True)
        return p


class _NodeSlot:
    """Runtime bookkeeping of one node: instance, context, counters, next tick."""

    def __init__(self, rt: GroupRuntime, rn: ResolvedNode, state_dir: Path | None) -> None:
        self.rn = rn
        self.id = rn.spec.id
        slot_keys = [f"out:{p}" for p in sorted(rn.cls.output_types(rn.params))] + [
            f"in:{p}" for p in sorted(rn.spec.inputs)
        ]
        self.state = SeqState(seq_file(state_dir, self.id) if state_dir else None, slot_keys)
        self.ctx = NodeContext(rt, rn, self.state)
        self.node: Node = rn.cls(rn.params, self.ctx)
        self.handled = dict.fromkeys(rn.spec.inputs, 0)
        self.gaps = dict.fromkeys(rn.spec.inputs, 0)
        topics = {
            port: keys.topic_key(rt.graph.name, *source.partition("/")[::2]) for port, source in rn.spec.inputs.items()
        }
        self.drops = DropLedger(self.id, topics, self.ctx.log)
        rate = self.node.tick_rate_hz()
        self.period_ns = int(1e9 / rate) if rate else 0
        self.ticks = 0

    def note_seq(self, port: str, seq: int) -> None:
        last = self.state.get("in:" + port)
        if last and seq > last + 1:
            self.gaps[port] += seq - last - 1
        self.state.set("in:" + port, seq)

    def health(self, state: str = "ok") -> Status:
        """Counters; ``seq.out.<port>``/``seq.in.<port>`` (last sequence published/seen) let the launcher
        drain the graph at shutdown, also across restarts (:meth:`Launcher.stop`)."""
        counters: dict[str, float] = {"ticks": self.ticks}
        counters.update({f"handled.{p}": n for p, n in self.handled.items()})
        counters.update({f"gaps.{p}": n for p, n in self.gaps.items()})
        counters.update({f"dropped.{p}": n for p, n in self.drops.counts().items()})
        counters.update({f"published.{p}": n for p, n in self.ctx.published.items()})
        counters.update({f"shm.{p}": n for p, n in self.ctx.shared.items()})
        counters.update({f"path.{p}": n for p, n in self.ctx.paths.items()})
        counters.update({f"seq.{k.replace(':', '.')}": self.state.get(k) for k in self.state.index})
        return Status(state=state, counters=counters, text=f"pid {os.getpid()}")


def _login(graph: Graph, user: str | None) -> dict[str, str] | None:
    """The node's ``usrpwd`` login in a user/password graph, read from the graph's credentials file."""
    if graph.spec.zenoh.usrpwd is None:
        return None
    creds = read_credentials(graph.base_dir / graph.spec.zenoh.usrpwd.credentials)
    user = user or graph.spec.zenoh.usrpwd.user
    return usrpwd_settings(creds, creds.login(user, "--user NAME")[0])


class GroupRuntime:
    """Runs the named nodes of a graph in this process until stopped."""

    def __init__(
        self,
        graph: Graph,
        node_ids: list[str],
        hub: str,
        lockstep: bool = False,
        state_dir: Path | None = None,
        user: str | None = None,
    ) -> None:
        self.graph = graph
        self.lockstep = lockstep
        self.virtual_ns = 0
        self.stop_requested = False
        self.settle = True  # at the stop, handle inputs until they go quiet (not for a restart of this process alone)
        self.closed = False  # inputs are no longer handled (after the stop's settling)
        self._last_input = 0.0  # monotonic time of the last input handled
        login = _login(graph, user)
        self.session = transport.open_node_session(graph.spec.zenoh, hub, login)
        self.shared = SharedPayloads(graph.spec.zenoh.shared_memory)
        self.local = local_routes.open_for(graph, hub, node_ids)
        self._local_sources = local_routes.local_sources(graph, node_ids) if self.local else set()
        self.inbox = wakeup_queue()  # lock-step clock events; None wakes the loop
        self._lock = threading.Lock()
        self.failure: str | None = None
        self.failure_reason: str | None = None  # one line of ``failure``, for the launcher's summary
        self.set_up = False
        self.started = threading.Event()
        self._report_now = False  # the launcher asked for a heartbeat (keys.report_key)
        self.live_params = NodeParams(  # before the slots: a restart's new values
            self, node_ids, state_dir, lambda: transport.open_node_session(graph.spec.zenoh, hub, login)
        )
        self.slots = [_NodeSlot(self, graph.nodes[nid], state_dir) for nid in node_ids]
        self._subs = []
        self._health_pubs = {
            s.id: self.session.declare_publisher(keys.topic_key(graph.name, s.id, "_health")) for s in self.slots
        }
        self._events_pub = self.session.declare_publisher(keys.events_key(graph.name))
        self._progress_pubs = (
            {s.id: self.session.declare_publisher(keys.topic_key(graph.name, s.id, "_progress")) for s in self.slots}
            if lockstep
            else {}
        )

    @property
    def lock(self) -> threading.Lock:
        """Held while a node's code runs (:class:`.live_params.ParamRuntime`)."""
        return self._lock

    # -- clock ------------------------------------------------------------------------------
    def now_ns(self) -> int:
        return self.virtual_ns if self.lockstep else time.time_ns()

    # -- wiring -----------------------------------------------------------------------------
    def output_port(self, key: str, cls: type[Message]) -> local_routes.OutputPort:
        local = self.local.publisher(key, local_routes.is_bulky(cls)) if self.local else None
        return local_routes.OutputPort(self.session.declare_publisher(key), local)

    def _subscribe(self) -> None:
        g = self.graph.name
        for slot in self.slots:
            for port, source in slot.rn.spec.inputs.items():
                node, _, out = source.partition("/")
                key = keys.topic_key(g, node, out)
                if node in self._local_sources:
                    bulky = local_routes.is_bulky(slot.rn.cls.input_types(slot.rn.params).get(port, Message))
                    self.local.subscribe(
                        key, lambda payload, att, s=slot, p=port: self._on_sample(s, p, payload, att), bulky
                    )
                    continue
                self._subs.append(
                    self.session.declare_subscriber(
                        key, lambda sample, s=slot, p=port: self._on_sample(s, p, *wire.sample_parts(sample))
                    )
                )
        if self.local:
            self.local.start()
        if self.lockstep:
            self._subs.append(
                self.session.declare_subscriber(
                    keys.clock_key(g), lambda sample: self.inbox.put(sample.payload.to_bytes())
                )
            )
        else:
            self._subs.append(self.session.declare_subscriber(keys.start_key(g), lambda _: self.started.set()))
        self._subs.append(self.session.declare_subscriber(keys.report_key(g), self._on_report_request))
        self.live_params.declare()

    def _on_report_request(self, _sample) -> None:
        self._report_now = True
        self.inbox.put(None)  # wakes the main loop

    def _await_start(self) -> None:
        """Report ready (heartbeats) until the launcher's start signal: no source ticks before every node listens."""
        deadline = time.monotonic() + START_WAIT_S
        while not (self.started.is_set() or self.stop_requested):
            self._publish_health()
            if time.monotonic() >= deadline:
                log.warning("no start signal from a launcher within %.0fs; starting anyway", START_WAIT_S)
                return
            self.started.wait(HEARTBEAT_S / 5)

    def _on_sample(self, slot: _NodeSlot, port: str, payload: bytes, att: bytes | None) -> None:
        """Zenoh or iceoryx2 callback: handle the message right here, serialised with ticks by the lock."""
        with self._lock:
            if self.closed or self.failure is not None:
                return
            self._last_input = time.monotonic()
            try:
                self._deliver(slot, port, payload, att)
                if self.lockstep:
                    self._publish_progress(slot)
            except Exception as exc:
                self.failure = f"node '{slot.id}' failed in on_message('{port}'):\n{traceback.format_exc()}"
                self.failure_reason = f"node '{slot.id}' failed in on_message('{port}'): {type(exc).__name__}: {exc}"
                self.stop_requested = True
                self.inbox.put(None)

    # -- main loop --------------------------------------------------------------------------
    def run(self, duration_s: float | None = None) -> int:
        """Set up, then tick (wall clock, or the replayer's virtual clock) until stopped; raise on a node
        failure (:class:`SetupError` for one during setup)."""
        for slot in self.slots:
            try:
                slot.node.setup()
            except Exception as exc:
                raise SetupError(slot.id, exc) from exc
        self.set_up = True
        self._subscribe()
        if not self.lockstep:
            self._await_start()
        start = time.monotonic()
        ticks: list[tuple[int, int]] = []  # (due ns, slot index)
        t0 = time.time_ns()
        for i, slot in enumerate(self.slots):
            if slot.period_ns:
                heapq.heappush(ticks, (t0 + slot.period_ns, i))
        next_health = 0.0
        clock_started = False
        while not self.stop_requested:
            now_m = time.monotonic()
            if duration_s is not None and now_m - start >= duration_s:
                break
            if now_m >= next_health or self._report_now:
                self._report_now = False
                self._publish_health()
                next_health = now_m + HEARTBEAT_S
            timeout = HEARTBEAT_S
            if ticks and not self.lockstep:
                timeout = min(timeout, max(0.0, (ticks[0][0] - time.time_ns()) / 1e9))
            try:
                clock = self.inbox.get(timeout=timeout) if timeout > 0 else None
            except queue.Empty:
                clock = None
            with self._lock:
                if self.stop_requested:
                    break
                if clock is not None:
                    target = int(json.loads(clock)["t_ns"])
                    if not clock_started:  # first clock: anchor the tick schedules at the replay start
                        ticks = [(target + self.slots[i].period_ns, i) for _, i in ticks]
                        heapq.heapify(ticks)
                        clock_started = True
                    self._run_due_ticks(ticks, target)
                    self.virtual_ns = max(self.virtual_ns, target)
                    for s in self.slots:
                        self._publish_progress(s, clock=target)
                elif not self.lockstep:
                    self._run_due_ticks(ticks, time.time_ns())
        if self.failure:
            raise RuntimeError(self.failure)
        return 0

    def _run_due_ticks(self, ticks: list[tuple[int, int]], until_ns: int) -> None:
        while ticks and ticks[0][0] <= until_ns:
            due, i = heapq.heappop(ticks)
            slot = self.slots[i]
            if self.lockstep:
                self.virtual_ns = due
            self.live_params.handling(slot.id, self.now_ns())
            try:
                slot.node.tick()
            except Exception as exc:
                self.failure_reason = f"node '{slot.id}' failed in tick(): {type(exc).__name__}: {exc}"
                raise
            slot.ticks += 1
            nxt = due + slot.period_ns
            if not self.lockstep and nxt < until_ns - 5 * slot.period_ns:
                nxt = until_ns  # fell far behind: skip missed ticks instead of bursting
            heapq.heappush(ticks, (nxt, i))

    def _deliver(self, slot: _NodeSlot, port: str, payload: bytes, att: bytes | None) -> None:
        expected = slot.rn.cls.input_types(slot.rn.params).get(port, Message)
        try:
            msg = wire.unpack(payload, att)
            if not isinstance(msg, expected):
                raise MessageError(f"input '{port}' takes {expected.TYPE}, got {msg.TYPE}")
        except MessageError as exc:
            slot.drops.note(port, str(exc))
            return
        slot.note_seq(port, msg.header.seq)
        if self.lockstep:
            self.virtual_ns = max(self.virtual_ns, msg.header.stamp_ns)
        self.live_params.handling(slot.id, msg.header.stamp_ns)
        slot.ctx.receiving(msg, None if att is None else payload)
        try:
            slot.node.on_message(port, msg)
        except MessageError as exc:  # the node cannot use this payload (or its output from it)
            slot.drops.note(port, str(exc))
            return
        finally:
            slot.ctx.receiving(None)
        slot.handled[port] += 1

    def _publish_health(self, state: str = "ok") -> None:
        for slot in self.slots:
            status = slot.health(state)
            status.header = Header(slot.id, 0, time.time_ns())
            payload, att = wire.pack(status)
            self._health_pubs[slot.id].put(payload, attachment=att)
            with self._lock:
                events = slot.drops.report()
            for event in events:
                event.header = Header(slot.id, 0, time.time_ns())
                payload, att = wire.pack(event)
                self._events_pub.put(payload, attachment=att)

    def _publish_progress(self, slot: _NodeSlot, clock: int | None = None) -> None:
        body = {"handled": slot.handled, "published": slot.ctx.published, "clock": clock}
        self._progress_pubs[slot.id].put(json.dumps(body))

    # -- shutdown ---------------------------------------------------------------------------
    def shutdown(self) -> None:
        self.stop_requested = True
        if self.set_up and self.failure is None and self.settle:
            self._let_inputs_settle()
        with self._lock:
            self.closed = True
        for sub in self._subs:
            sub.undeclare()
        if self.local:
            self.local.stop()
        with self._lock:
            self._teardown_all()
            self.live_params.close()
        if self.set_up:  # the last counters, after teardown's last outputs: the launcher's summary and its
            self._publish_health(STOPPED)  # drain (STOPPED); a node that never set up is not ready
        if self.local:
            self.local.close()
        self.session.close()

    def _let_inputs_settle(self) -> None:
        """Ticks have stopped; inputs are still handled until none came for ``SETTLE_QUIET_S`` (at most
        ``SETTLE_MAX_S``), so that the last messages of upstream nodes stopped at the same moment — a
        cycle of units, which the launcher stops together — are handled and their outputs published
        (docs/recording.md, "Recording")."""
        deadline = time.monotonic() + SETTLE_MAX_S
        while (now := time.monotonic()) < deadline and now - self._last_input < SETTLE_QUIET_S:
            time.sleep(0.01)

    def _teardown_all(self) -> None:
        for slot in self.slots:
            try:
                for port, msg in slot.node.safe_output().items():
                    slot.ctx.publish(port, msg)
                slot.node.teardown()
            except Exception:
                log.error("teardown of node '%s' failed:\n%s", slot.id, traceback.format_exc())


def _exit_with_parent(parent: int) -> None:
    """No node outlives its launcher: when the parent process is gone (even SIGKILLed), stop in order,
    and exit hard if that takes longer than ``ORPHAN_GRACE_S`` (docs/pipelines.md)."""
    while os.getppid() == parent:
        time.sleep(ORPHAN_POLL_S)
    log.warning("the launcher (pid %d) is gone; stopping", parent)
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(ORPHAN_GRACE_S)
    os._exit(1)


def main(argv: list[str] | None = None, parent: int | None = None) -> int:
    """Run the nodes; stop with the ``parent`` process (default: the one that started this one)."""
    parent = os.getppid() if parent is None else parent
    ap = argparse.ArgumentParser(
        prog="python -m handflow.framework.runtime.runner", description="Run nodes of a graph (used by the launcher)."
    )
    ap.add_argument("graph")
    ap.add_argument("--nodes", required=True, help="comma-separated node ids")
    ap.add_argument("--hub", required=True, help="zenoh endpoint of the launcher's hub session")
    ap.add_argument("--lockstep", action="store_true")
    ap.add_argument("--state-dir", type=Path)
    ap.add_argument("--log-level", default="INFO")
    ap.add_argument("--user", help="login of a 'zenoh.usrpwd' graph (password from its credentials file)")
    ap.add_argument("--graph-text", type=Path, help="the graph file's content to run (kept by `handflow run --watch`)")
    args = ap.parse_args(argv)
    logging.basicConfig(
        level=args.log_level, stream=sys.stderr, format="%(asctime)s %(levelname)s [%(name)s] %(message)s"
    )
    node_ids = args.nodes.split(",")
    graph = load_graph(args.graph, only=node_ids, text=args.graph_text.read_text() if args.graph_text else None)
    rt = GroupRuntime(graph, node_ids, args.hub, args.lockstep, args.state_dir, args.user)

    def _stop(signum, frame):
        rt.stop_requested = True
        rt.settle = signum != RESTART_SIGNAL

    for sig in (signal.SIGTERM, signal.SIGINT, RESTART_SIGNAL):
        signal.signal(sig, _stop)
    threading.Thread(target=_exit_with_parent, args=(parent,), daemon=True).start()
    faulthandler.register(signal.SIGUSR1, all_threads=True)  # the launcher asks for stacks before a kill
    code, failure = 0, None
    try:
        rt.run()
    except SetupError as exc:
        if not isinstance(exc.cause, EXPECTED_ERRORS):
            log.error("%s\n%s", exc, "".join(traceback.format_exception(exc.cause)))
        elif args.state_dir is None:  # else the launcher reports the node's own message, once
            log.error("%s", exc)
        cause = exc.cause
        reason = str(cause) if isinstance(cause, EXPECTED_ERRORS) else f"{type(cause).__name__}: {cause}"
        code, failure = 1, {"phase": "setup", "reason": f"node '{exc.node_id}': {reason}"}
    except Exception as exc:
        log.error("node group %s crashed:\n%s", args.nodes, traceback.format_exc())
        code, failure = 1, {"phase": "running", "reason": rt.failure_reason or f"{type(exc).__name__}: {exc}"}
    finally:
        rt.shutdown()
    if failure is not None and args.state_dir is not None:
        failure_file(args.state_dir, node_ids).write_text(json.dumps(failure))
    return code


if __name__ == "__main__":
    sys.exit(main())
