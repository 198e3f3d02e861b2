"""Launch and supervise a graph: one process per node or per group (docs/pipelines.md, "Running").

The launcher opens the hub Zenoh session, starts a :mod:`handflow.framework.runtime.runner` process per unit,
restarts crashed units according to their restart policy (default ``on-failure``: capped
exponential backoff; more than ``max_restarts`` failures within ``window_s``, or a failure during
setup with the same error as the one before, is a crash loop, reported with the unit's last log
lines, after which it stays down), publishes every restart and crash loop as a
:class:`RuntimeEvent`, and on Ctrl-C, SIGTERM or the end of ``--duration`` stops the units
upstream first, each once the units it feeds have drained (their teardown runs; see
:meth:`Launcher.stop`), and reports which nodes failed and why (docs/reliability.md).  It also
serves ``handflow param`` for its nodes (:mod:`.param_service`, docs/tuning.md) and, with
``--watch``, restarts the nodes an edit of the graph file or of a plugin concerns (:mod:`.watch`).
"""

from __future__ import annotations

import collections
import contextlib
import json
import logging
import queue
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Collection
from dataclasses import dataclass, field
from pathlib import Path

from .. import keys, wire
from ..graphs.model import Graph, RestartPolicy
from ..messages import Header, MessageError, RuntimeEvent, Status
from ..network import hub_info, local_transport
from ..network import sessions as transport
from . import discovery
from .live_params import forget_edited_params
from .param_service import ParamService
from .ros2_bridge import Ros2Bridge
from .runner import RESTART_SIGNAL, START_WAIT_S, STOPPED, failure_file, node_state_files
from .startup import StartupProgress
from .stop_signals import StopSignals
from .watch import Watcher
from .zygote import RUNNER, ForkedProcess, Zygote, start_unless_disabled

log = logging.getLogger("handflow.launcher")

STOP_GRACE_S = 8.0
DRAIN_S = 5.0  # at shutdown, how long nodes may take to handle what the nodes upstream published last
LOG_TAIL = 20  # lines of a unit's log kept for a crash report


@dataclass
class Unit:
    """A process running one or more nodes, with its restart bookkeeping."""

    name: str
    node_ids: list[str]
    policy: RestartPolicy
    proc: subprocess.Popen | ForkedProcess | None = None
    restarts: int = 0
    restart_at: float | None = None
    exit_codes: list[int] = field(default_factory=list)
    failures: list[float] = field(default_factory=list)  # monotonic times of recent failures
    gave_up: str | None = None  # why supervision stopped restarting it (a crash loop)
    failure: dict | None = None  # the last failure: phase ("setup" or "running") and reason
    attempts: int = 0  # starts that ended in that same failure, in a row
    running_at_end: bool = False
    log_tail: collections.deque = field(default_factory=lambda: collections.deque(maxlen=LOG_TAIL))


def plan_units(graph: Graph, host: str | None = None) -> list[Unit]:
    """Group the graph's nodes (for ``host``) into process units; a group's policy is its most permissive one."""
    units: dict[str, Unit] = {}
    for nid, rn in graph.nodes.items():
        if rn.spec.host != host:
            continue
        key = f"group:{rn.spec.group}" if rn.spec.group else nid
        unit = units.setdefault(key, Unit(rn.spec.group or nid, [], rn.spec.restart))
        if unit.node_ids and rn.spec.restart.policy == "on-failure":
            unit.policy = rn.spec.restart if unit.policy.policy == "never" else unit.policy
        unit.node_ids.append(nid)
    return list(units.values())


class Launcher:
    """Runs a validated graph until stopped; see :func:`run_graph`."""

    def __init__(
        self,
        graph: Graph,
        host: str | None = None,
        lockstep: bool = False,
        log_level: str = "INFO",
        zygote: Zygote | None = None,
        graph_text: str | None = None,
    ) -> None:
        self.graph = graph
        self.host = host
        self.units = plan_units(graph, host)
        if not self.units:
            where = f" for host '{host}'" if host else ""
            raise ValueError(f"graph '{graph.name}' has no nodes to run{where}; check the nodes' 'host' fields")
        self.lockstep = lockstep
        self.log_level = log_level
        # before any Zenoh session: it forks the node processes (docs/architecture.md, "Process start-up")
        self.zygote = zygote or start_unless_disabled(graph.path)
        self.hub_endpoint = transport.hub_endpoint_for()
        self._state_dir = tempfile.TemporaryDirectory(prefix=f"handflow-{graph.name}-")
        self.user: str | None = None
        with contextlib.ExitStack() as undo:  # if the start-up fails (or is interrupted), close what it opened
            if self.zygote is not None:
                undo.callback(self.zygote.close)
            undo.callback(self._state_dir.cleanup)
            self.session = transport.open_hub(graph.spec.zenoh, self.hub_endpoint, self._secure_settings(host))
            undo.callback(self.session.close)
            self.stopping = False
            self.edited: set[Path] = set()  # plugin source files edited during the run (`--watch`, docs/tuning.md)
            self.graph_text: Path | None = None  # the version of the graph file the nodes run (`--watch`)
            if graph_text is not None:
                self.graph_text = self.state_dir / "graph.yaml"
                self.graph_text.write_text(graph_text)
            self.run_file = discovery.write_run_file(
                graph.name, self.hub_endpoint, graph.path, lockstep, usrpwd=self.user is not None
            )
            undo.callback(discovery.remove_run_file, self.run_file)
            self.health: dict[str, Status] = {}
            self._health_sub = self.session.declare_subscriber(
                keys.topic_key(graph.name, "*", "_health"), self._on_health
            )
            self._start_pub = self.session.declare_publisher(keys.start_key(graph.name))
            self._report_pub = self.session.declare_publisher(keys.report_key(graph.name))
            self._event_pub = self.session.declare_publisher(keys.topic_key(graph.name, "_runtime", "events"))
            self._event_seq = 0
            self._info = hub_info.declare_info(
                self.session, graph.name, host, list(graph.nodes), list(graph.spec.external)
            )
            self.ros2 = Ros2Bridge(self.session, graph, host) if graph.spec.ros2 is not None else None
            if self.ros2 is not None:
                undo.callback(self.ros2.close)
            self._calls: queue.SimpleQueue = queue.SimpleQueue()  # run by poll(), the supervising thread
            self.params = ParamService(self)
            undo.pop_all()
        self._local_prepared = None
        if graph.spec.transport.local == "iceoryx2":  # beside the start-up: importing iceoryx2 takes 0.2-0.6 s
            self._local_prepared = threading.Thread(target=_prepare_local, name="handflow-iox2", daemon=True)
            self._local_prepared.start()

    def _secure_settings(self, host: str | None) -> dict[str, object]:
        """The hub's TLS, access-control and user/password settings (docs/security.md)."""
        secure: dict[str, object] = {}
        if self.graph.spec.zenoh.tls is not None:
            from ..security import access

            secure["tls"] = access.tls_settings(self.graph, host)
            secure["access_control"] = access.access_control(self.graph, host)
        if self.graph.spec.zenoh.usrpwd is not None:
            from ..security import credentials

            creds, self.user = credentials.graph_credentials(self.graph.spec.zenoh.usrpwd, self.graph.base_dir, host)
            dictionary = credentials.write_dictionary(creds, self._state_dir.name)
            secure["usrpwd"] = credentials.usrpwd_settings(creds, self.user, dictionary)
        return secure

    def _on_health(self, sample) -> None:
        try:
            status = wire.unpack(*wire.sample_parts(sample))
        except MessageError:
            return
        self.health[status.header.source] = status

    @property
    def state_dir(self) -> Path:
        """The run's folder of node state (sequence numbers, failures, parameters set while running)."""
        return Path(self._state_dir.name)

    def call_soon(self, call) -> None:
        """Run ``call()`` in the supervising thread, at its next :meth:`poll` (from other threads)."""
        self._calls.put(call)

    def ready(self, unit: Unit) -> bool:
        """The unit runs and each of its nodes has reported since its start (set up, inputs subscribed)."""
        return unit.proc is not None and all(nid in self.health for nid in unit.node_ids)

    def all_ready(self) -> bool:
        return all(self.ready(u) for u in self.units)

    def settled(self) -> bool:
        """Every unit is ready or down for good (crash loop, restart policy 'never', exited)."""
        return all(self.ready(u) or (u.proc is None and u.restart_at is None) for u in self.units)

    def signal_start(self) -> None:
        """Let the nodes tick; repeated while running so that a restarted unit starts too."""
        self._start_pub.put(b"start")

    # -- processes --------------------------------------------------------------------------
    def start_process(
        self, module: str, args: list[str], what: str, edited: Collection[Path] = ()
    ) -> subprocess.Popen | ForkedProcess:
        """A process running ``module.main(args)``: forked from the zygote (its plugins already imported;
        those edited during the run, or in ``edited``, imported afresh: :mod:`.plugin_sources`), else a
        new interpreter."""
        forget = {str(f) for f in (*self.edited, *edited)}
        proc = self.zygote.spawn(args, module, forget) if self.zygote is not None else None
        if proc is not None:
            return proc
        if self.zygote is not None:
            log.warning("the zygote cannot fork %s; starting it as a new interpreter", what)
        return subprocess.Popen(
            [sys.executable, "-m", module, *args],
            start_new_session=True,
            stderr=subprocess.PIPE,
            text=True,
            errors="replace",
            bufsize=1,
        )

    def _spawn(self, unit: Unit) -> None:
        """Start the unit's process (:meth:`start_process`), its log forwarded to ours."""
        args = [
            str(self.graph.path),
            "--nodes",
            ",".join(unit.node_ids),
            "--hub",
            self.hub_endpoint,
            "--state-dir",
            self._state_dir.name,
            "--log-level",
            self.log_level,
        ]
        if self.lockstep:
            args.append("--lockstep")
        if self.user is not None:  # the node reads its password from the graph's credentials file
            args += ["--user", self.user]
        if self.graph_text is not None:
            args += ["--graph-text", str(self.graph_text)]
        for nid in unit.node_ids:  # ready again only once the new process reports
            self.health.pop(nid, None)
        unit.proc = self.start_process(RUNNER, args, unit.name)
        threading.Thread(target=_forward_log, args=(unit.proc.stderr, unit.log_tail), daemon=True).start()
        log.info("started %s (pid %d)", unit.name, unit.proc.pid)

    def start(self) -> None:
        if self._local_prepared is not None:  # its reclaiming of dead nodes' files must not meet a node being made
            self._local_prepared.join()
        for unit in self.units:
            self._spawn(unit)

    def reset(self) -> None:
        """Stop every unit and start it afresh, as at the graph's start: its nodes' sequence numbers and
        parameters set while running are forgotten (a lock-step replay seeking back, docs/recording.md)."""
        self._terminate([u for u in self.units if u.proc is not None], RESTART_SIGNAL)  # no settling: restarted
        for unit in self.units:  # one waiting to be restarted starts now, once
            unit.restart_at = None
        for nid in self.graph.nodes:
            for path in node_state_files(self.state_dir, nid):
                path.unlink(missing_ok=True)
        self.start()

    def event(self, kind: str, unit: Unit, detail: str) -> None:
        """Publish a :class:`RuntimeEvent` (seen by monitor, written into recordings)."""
        msg = RuntimeEvent(kind=kind, node=",".join(unit.node_ids), detail=detail)
        msg.header = Header("_launcher", self._event_seq, time.time_ns())
        self._event_seq += 1
        payload, att = wire.pack(msg)
        self._event_pub.put(payload, attachment=att)

    @property
    def crash_loops(self) -> list[str]:
        return [u.gave_up for u in self.units if u.gave_up]

    def failure_report(self) -> tuple[list[str], bool]:
        """One line per unit that failed (why, whether it ran at the end) and whether one was down at the end."""
        lines, down = [], False
        for u in self.units:
            if u.failure is None:
                continue
            down |= not u.running_at_end
            state = (
                f"crash loop after {len(u.exit_codes)} failed starts, not restarted"
                if u.gave_up
                else f"restarted {u.restarts}x, running at the end"
                if u.running_at_end
                else "not running at the end"
            )
            where = f"{self.graph.path}:{self.graph.nodes[u.node_ids[0]].line}"
            why = (  # the same message again and again: printed once, as it first happened
                f"failed {u.attempts} times with the same error, logged above at its first failure"
                if u.attempts > 1
                else f"failed {_why(u.failure)}"
            )
            lines.append(f"{where}: {', '.join(u.node_ids)} ({state}): {why}")
        return lines, down

    def _failure(self, unit: Unit, code: int) -> dict:
        """Why the unit's process failed: what it reported (:func:`.runner.failure_file`), else its exit status."""
        path = failure_file(self._state_dir.name, unit.node_ids)
        why = f"killed by signal {-code}" if code < 0 else f"exit code {code}"
        try:
            failure = json.loads(path.read_text())
            path.unlink()
        except (OSError, ValueError):
            return {"phase": "running", "reason": why}
        return failure if isinstance(failure, dict) else {"phase": "running", "reason": why}

    def poll(self) -> None:
        """Run the calls asked for (:meth:`call_soon`), reap exited units and restart them per policy."""
        while not self._calls.empty():
            self._calls.get()()
        now = time.monotonic()
        for unit in self.units:
            if unit.proc is not None and (code := unit.proc.poll()) is not None:
                unit.proc = None
                unit.exit_codes.append(code)
                if code == 0 or self.stopping:
                    log.info("%s exited normally", unit.name)
                    continue
                why = f"killed by signal {-code}" if code < 0 else f"exit code {code}"
                previous, unit.failure = unit.failure, self._failure(unit, code)
                repeated = previous == unit.failure  # its message was logged already: said once (docs/reliability.md)
                unit.attempts = unit.attempts + 1 if repeated else 1
                unit.failures = [t for t in unit.failures if now - t <= unit.policy.window_s] + [now]
                failed = (
                    f"{unit.name} failed again with the same error (attempt {unit.attempts})"
                    if repeated
                    else f"{unit.name} failed {_why(unit.failure)}"
                )
                if unit.policy.policy == "never":
                    log.error("%s; restart policy 'never': the rest of the graph keeps running", failed)
                elif (repeated and unit.failure["phase"] == "setup") or len(unit.failures) > unit.policy.max_restarts:
                    unit.gave_up = (
                        f"{unit.name} failed during setup {unit.attempts} times with the same error"
                        if repeated and unit.failure["phase"] == "setup"
                        else f"{unit.name} failed {len(unit.failures)} times within {unit.policy.window_s:.0f}s"
                    )
                    reason = " (above)" if repeated else f" (last: {unit.failure['reason']})"
                    tail = "".join(f"\n    {line}" for line in unit.log_tail)
                    log.error(
                        "crash loop: %s%s; not restarted again%s",
                        unit.gave_up,
                        reason,
                        tail and "; its last log lines:" + tail,
                    )
                    self.event("crash_loop", unit, f"{unit.gave_up}: {unit.failure['reason']}; not restarted again")
                else:
                    delay = min(unit.policy.max_backoff_s, unit.policy.backoff_s * 2 ** (len(unit.failures) - 1))
                    unit.restart_at = now + delay
                    log.warning("%s; restarting in %.2fs", failed, delay)
                    self.event("restart", unit, f"{why}; restart in {delay:.2f}s")
            if unit.proc is None and unit.restart_at is not None and now >= unit.restart_at:
                unit.restart_at = None
                unit.restarts += 1
                self._spawn(unit)

    def restart(self, unit: Unit, why: str) -> None:
        """Stop ``unit`` in order and start it again at once (a parameter it takes only at start changed)."""
        self._terminate([unit])
        self.event("restart", unit, why)
        self._spawn(unit)

    def reload(self, graph: Graph, text: str, touched: set[str], why: str) -> list[str]:
        """Run ``graph``, an edit of the running one (``handflow run --watch``, docs/tuning.md): stop the
        units hosting a node of ``touched`` (its entry or plugin changed) or a node the edit removed, and
        start the units of the new plan that are not running unchanged; the other units keep running.
        Returns one line per unit started or stopped."""
        forget_edited_params(self.state_dir, self.graph, graph)
        self.graph_text.write_text(text)  # what every node process started from now on runs
        old = {_key(u): u for u in self.units}
        new = plan_units(graph, self.host)
        kept = {_key(u) for u in new if _key(u) in old and touched.isdisjoint(u.node_ids)}
        stopped = [u for key, u in old.items() if key not in kept]
        self._terminate([u for u in stopped if u.proc is not None], RESTART_SIGNAL)
        for u in stopped:
            for nid in u.node_ids:
                self.health.pop(nid, None)
        self.graph = graph
        self.units = [old[_key(u)] if _key(u) in kept else u for u in new]
        started = [u for u in self.units if _key(u) not in kept]
        for u in started:
            self._spawn(u)
        before = {nid for u in stopped for nid in u.node_ids}
        running = {nid for u in self.units for nid in u.node_ids}
        done = [("restarted" if before & set(u.node_ids) else "started", u) for u in started]
        done += [("stopped", u) for u in stopped if running.isdisjoint(u.node_ids)]
        for verb, u in done:
            self.event("reload", u, f"{verb}: {why}")
        self.params.serve([nid for u in self.units for nid in u.node_ids])
        self._info.undeclare()
        self._info = hub_info.declare_info(
            self.session, graph.name, self.host, list(graph.nodes), list(graph.spec.external)
        )
        return [f"{verb} {', '.join(u.node_ids)}" for verb, u in done]

    def alive(self) -> bool:
        return any(u.proc is not None or u.restart_at is not None for u in self.units)

    def stop(self) -> None:
        """Orderly shutdown, upstream first: SIGTERM the units no running unit feeds (teardown runs), wait
        until the units they feed have seen the last message they published (heartbeat ``seq.*``
        counters, at most ``DRAIN_S``), then stop those; SIGKILL stragglers after ``STOP_GRACE_S``.
        So every message published before the stop is handled downstream and recorded (a cycle of
        units stops together: each stops ticking and handles its inputs until they go quiet, see
        ``GroupRuntime.shutdown``; docs/recording.md, "Recording")."""
        self.stopping = True
        for u in self.units:
            u.running_at_end = u.proc is not None
        remaining = [u for u in self.units if u.proc is not None]
        stopped: set[str] = set()
        while remaining:
            fed = {u.name for u in remaining for v in remaining if v is not u and self._feeds(v, u)}
            wave = [u for u in remaining if u.name not in fed] or remaining
            remaining = [u for u in remaining if u not in wave]
            self._terminate(wave)
            stopped.update(nid for u in wave for nid in u.node_ids)
            self._drain(wave, stopped, remaining)

    def _feeds(self, upstream: Unit, downstream: Unit) -> bool:
        sources = {src.partition("/")[0] for nid in downstream.node_ids for src in self._inputs(nid).values()}
        return not sources.isdisjoint(upstream.node_ids)

    def _inputs(self, nid: str) -> dict[str, str]:
        return self.graph.nodes[nid].spec.inputs

    def _terminate(self, units: list[Unit], sig: int = signal.SIGTERM) -> None:
        for u in units:
            for nid in u.node_ids:  # a last heartbeat of an earlier process must not count as this one's
                if nid in self.health and self.health[nid].state == STOPPED:
                    del self.health[nid]
            u.proc.send_signal(sig)
        deadline = time.monotonic() + STOP_GRACE_S
        for u in units:
            while u.proc.poll() is None and time.monotonic() < deadline:
                self._report_pub.put(b"report")  # wakes the node's main loop: it sees the SIGTERM at once
                time.sleep(0.02)
            try:
                u.proc.wait(timeout=0.1)
            except subprocess.TimeoutExpired:
                log.error(
                    "%s did not stop within %.0fs; its threads' stacks follow, then it is killed", u.name, STOP_GRACE_S
                )
                u.proc.send_signal(signal.SIGUSR1)
                time.sleep(0.5)
                u.proc.kill()
                u.proc.wait()
            u.exit_codes.append(u.proc.returncode)
            u.proc = None

    def _drain(self, wave: list[Unit], stopped: set[str], running: list[Unit]) -> None:
        """Wait for the last heartbeats of ``wave`` (sent after all their messages) and until every running
        node has seen the last message each stopped node published to it."""

        def counter(nid: str, key: str) -> float:
            status = self.health.get(nid)
            return status.counters.get(key, 0) if status else 0

        def pending() -> list[str]:
            out = [
                f"{nid} (last heartbeat)"
                for u in wave
                if u.exit_codes[-1] == 0
                for nid in u.node_ids
                if self.health.get(nid) is None or self.health[nid].state != STOPPED
            ]
            for u in running:
                if u.proc is None or u.proc.poll() is not None:
                    continue
                for nid in u.node_ids:
                    for port, source in self._inputs(nid).items():
                        src, _, out_port = source.partition("/")
                        sent = counter(src, f"seq.out.{out_port}") if src in stopped else 0
                        if counter(nid, f"seq.in.{port}") < sent:
                            out.append(f"{source} → {nid}.{port}")
            return out

        deadline = time.monotonic() + DRAIN_S
        while (behind := pending()) and time.monotonic() < deadline:
            self._report_pub.put(b"report")  # fresh counters now, not at the next heartbeat
            time.sleep(0.02)
        if behind:
            log.warning("stopping: not drained within %.0fs: %s", DRAIN_S, ", ".join(behind))

    def close(self) -> None:
        discovery.remove_run_file(self.run_file)
        self.params.close()
        if self.ros2 is not None:
            self.ros2.close()
        self._health_sub.undeclare()
        self._start_pub.undeclare()
        self._report_pub.undeclare()
        self._event_pub.undeclare()
        self._info.undeclare()
        self.session.close()
        if self.zygote is not None:
            self.zygote.close()
        self._state_dir.cleanup()
        local_transport.remove_leftovers()

    def summary(self) -> dict[str, dict[str, object]]:
        """Per unit: nodes, restarts, exit codes, and per node the input gaps of its last heartbeat."""

        def gaps(nid: str) -> int:
            status = self.health.get(nid)
            return int(sum(v for k, v in status.counters.items() if k.startswith("gaps."))) if status else 0

        return {
            u.name: {
                "nodes": u.node_ids,
                "restarts": u.restarts,
                "exit_codes": u.exit_codes,
                "failure": u.failure,
                "running_at_end": u.running_at_end,
                "gaps": {nid: gaps(nid) for nid in u.node_ids},
            }
            for u in self.units
        }


def _key(unit: Unit) -> tuple[str, tuple[str, ...]]:
    """What makes a unit the same process in two versions of a graph: its name and its nodes."""
    return unit.name, tuple(unit.node_ids)


def _prepare_local() -> None:
    """Reclaim what dead processes left in iceoryx2; one notice when it is not usable (docs/shared_memory.md)."""
    if (why := local_transport.prepare()) is not None:
        log.warning(
            "iceoryx2 is not usable here (%s); this host's topics travel over Zenoh. %s",
            why,
            local_transport.remedy(why),
        )


def _why(failure: dict) -> str:
    """``during setup: REASON`` or ``(REASON)``, for log lines and the summary."""
    return f"during setup: {failure['reason']}" if failure["phase"] == "setup" else f"({failure['reason']})"


def _forward_log(stream, tail: collections.deque) -> None:
    """Copy a node process's log to ours, keeping its last lines for a crash report."""
    for line in stream:
        sys.stderr.write(line)
        tail.append(line.rstrip("\n"))


def run_graph(
    graph: Graph,
    duration_s: float | None = None,
    host: str | None = None,
    on_ready=None,
    lockstep: bool = False,
    zygote: Zygote | None = None,
    watch: bool = False,
    progress: StartupProgress | None = None,
    text: str | None = None,
    stop: StopSignals | None = None,
) -> Launcher:
    """Run ``graph`` until Ctrl-C/SIGTERM or ``duration_s``; returns the stopped launcher (for its summary).

    ``on_ready(launcher)`` runs once the hub session is open and before any node starts (attach a
    recorder or a live view there, so they miss nothing); if it raises, nothing is started.  A
    ``zygote`` started before the graph was loaded imports the plugins meanwhile (one is started otherwise).
    With ``watch``, edits of the graph file and of its plugins' sources restart the nodes they
    concern (:mod:`.watch`, docs/tuning.md).  ``progress`` says how start-up goes (:mod:`.startup`).
    With ``text``, the nodes run that version of the graph file (``handflow run --set``,
    :mod:`..graphs.overrides`).
    ``stop``: the caller's :class:`.stop_signals.StopSignals`, installed before its own start-up (else
    installed here); a stop before the nodes start starts none.  On any error the units are stopped and
    the launcher closed before it propagates.
    """
    if lockstep and watch:
        raise ValueError("--watch cannot be used in lock-step mode: a lock-step replay is a fixed, deterministic run")
    progress = progress or StartupProgress()
    if text is None and watch:
        text = graph.path.read_text()
    level = logging.getLevelName(logging.getLogger().level)
    with contextlib.ExitStack() as signals:
        if stop is None:
            stop = signals.enter_context(StopSignals())
        launcher = Launcher(graph, host, lockstep, level, zygote, graph_text=text)
        try:
            if on_ready is not None:
                on_ready(launcher)
            _supervise(launcher, stop, progress, duration_s, lockstep, text if watch else None)
        except BaseException:
            try:
                launcher.stop()
            finally:
                launcher.close()
            raise
    return launcher


def _supervise(
    launcher: Launcher,
    stop: StopSignals,
    progress: StartupProgress,
    duration_s: float | None,
    lockstep: bool,
    text: str | None,
) -> None:
    """Start the units and supervise them until ``stop`` or the end of ``duration_s``, then stop them."""
    watcher = None
    try:
        if not stop.is_set():  # a stop during the start-up: nothing is started
            launcher.start()
            watcher = Watcher(launcher, text) if text is not None else None
        t_launch = time.monotonic()
        t_end = None  # the duration counts from the moment every node is ready (or down for good)
        started = False
        while not stop.is_set() and (t_end is None or time.monotonic() < t_end):
            launcher.poll()
            if not launcher.alive():
                log.info("all nodes have exited")
                break
            if not started:
                progress.poll(launcher)
            ready = lockstep or launcher.all_ready()
            waited = time.monotonic() - t_launch
            settled = ready or launcher.settled() or waited > START_WAIT_S
            if settled and not started:
                started = True
                if ready:
                    progress.all_ready(waited)
                else:
                    down = [nid for u in launcher.units if u.proc is None for nid in u.node_ids]
                    log.warning("%.1fs after the launch, the other nodes start without %s", waited, ", ".join(down))
                if duration_s is not None:
                    t_end = time.monotonic() + duration_s
            if settled and not lockstep:
                launcher.signal_start()
            time.sleep(0.05)
    finally:
        if watcher is not None:
            watcher.close()
    launcher.stop()
