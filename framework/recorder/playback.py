"""A replay driven from Foxglove's playback bar: play, pause, seek, speed (docs/recording.md).

:class:`Playback` keeps the replay's position on the recording's clock and maps it to the wall
clock at the chosen speed.  :class:`ControlledReplayer` publishes the recording as
:class:`.replay.TimedReplayer` does, but waits on that clock, holds while paused and, after a seek,
starts again from the first message at or after the target (going back reads the file from the
start).  :class:`ControlledLockstep` releases the messages of a :class:`.replay.LockstepReplayer`
on that clock, each once the graph handled the one before: a seek forward releases the messages
up to the target as fast as the graph handles them, a seek back first restarts the graph's nodes
(their start state) and replays from the start up to the target the same way.  Until the replay
reaches the target, the Foxglove bridge forwards nothing, not even what the graph published on the
way and delivers late (:meth:`Playback.shows`), and the bar shows the target, status Buffering.  Only
the pass that took the seek (:meth:`Playback.take_seek`) reaches its target: one a seek interrupts,
even while a message is released, never does (:meth:`Playback.arrived`).  :class:`PlaybackListener`
answers Foxglove's PlaybackControl requests.
"""

from __future__ import annotations

import logging
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

try:  # the optional extra 'foxglove', 0.30 or newer for PlaybackControl
    from foxglove.websocket import PlaybackCommand, PlaybackState, PlaybackStatus, ServerListener
except ImportError as exc:
    SDK_MISSING: str | None = str(exc)
    ServerListener = object
else:
    SDK_MISSING = None

from ..files.mcap_reader import ReadReport, RecordedMessage, iter_recording
from .replay import LockstepReplayer, ReplayPlan, ReplayStats, _Publishers

log = logging.getLogger("handflow.replay")

TIME_EVERY_S = 0.1  # how often the playback bar hears the position
ANSWER_GRACE_S = 0.05
"""The replay's own playback states wait this long after an answer to the bar, which foxglove-sdk sends
when the request's callback returns (:class:`PlaybackListener`)."""


def time_range(path: Any) -> tuple[int, int]:
    """First and last log time of a recording."""
    first = last = None
    for rm in iter_recording(path):
        first = rm.log_time_ns if first is None else first
        last = rm.log_time_ns
    if first is None:
        raise ValueError(f"{path} holds no messages to replay")
    return first, last


class Playback:
    """Position, speed and play/pause of a replay, changed from another thread."""

    def __init__(self, start_ns: int, end_ns: int, speed: float = 1.0) -> None:
        self.start_ns, self.end_ns = start_ns, end_ns
        self.cond = threading.Condition()
        self.playing, self.speed, self.ended = True, float(speed), False
        self.seek_to: int | None = None  # a seek the replay has not taken yet
        self.seeking = False  # from a seek until the replay reaches its target
        self.hidden: dict[str, int] = {}  # topic key → the last sequence number published on the way there
        self.next_ns = start_ns  # the message waited for (a lock-step graph may lag behind the clock)
        self.answered_at = float("-inf")  # when the bar's last request was answered (monotonic)
        self._anchor = (time.monotonic(), start_ns)  # wall time ↔ recording time at the last change

    def position(self) -> int:
        """The recording time playing now."""
        wall, rec = self._anchor
        if not self.playing or self.seeking:
            return rec
        return min(self.end_ns, self.next_ns, rec + int((time.monotonic() - wall) * 1e9 * self.speed))

    def control(self, play: bool, speed: float, seek_ns: int | None) -> None:
        with self.cond:
            now = self.position() if seek_ns is None else min(max(int(seek_ns), self.start_ns), self.end_ns)
            self.playing = play
            self.speed = speed if speed > 0 else self.speed
            self._anchor = (time.monotonic(), now)
            if seek_ns is not None:
                self.seek_to, self.ended, self.seeking, self.next_ns = now, False, True, now
            self.cond.notify_all()

    def take_seek(self) -> int | None:
        """The target of the seek the replay takes now (None if none is pending); the pass that follows is
        the only one that can reach it (:meth:`arrived`)."""
        with self.cond:
            target, self.seek_to = self.seek_to, None
            return target

    def arrived(self, hidden: dict[str, int]) -> bool:
        """The replay reached the seek target: the clock runs on from the target, from now, and messages up to
        the sequence numbers in ``hidden`` (topic key → number) stay hidden; True if it was seeking.

        Only the pass that took the seek (:meth:`take_seek`) arrives: while a seek is pending, the replay
        is still on a pass started before it, whatever its position, and everything the graph computes
        on it belongs to frames before the target, so it stays hidden (False)."""
        with self.cond:
            if not self.seeking or self.seek_to is not None:
                return False
            self.seeking, self.hidden = False, hidden
            self._anchor = (time.monotonic(), self._anchor[1])
            return True

    def shows(self, key: str, seq: int) -> bool:
        """Whether Foxglove is shown message ``seq`` on ``key``: not while seeking, nor one published on the way."""
        return not self.seeking and seq > self.hidden.get(key, 0)

    def wait_for(self, log_ns: int, stop: threading.Event) -> bool:
        """Wait until the replay reaches ``log_ns``; False when a seek (or stop) came first."""
        with self.cond:
            if self.seek_to is None:  # a pending seek's target stays the message waited for
                self.next_ns = log_ns
            while not stop.is_set() and self.seek_to is None:
                if self.playing:
                    wall, rec = self._anchor
                    left = (log_ns - rec) / 1e9 / self.speed - (time.monotonic() - wall)
                    if left <= 0:
                        return True
                    self.cond.wait(min(left, 0.1))
                else:
                    self.cond.wait(0.1)
            return False

    def state(self, did_seek: bool = False, request_id: str | None = None) -> PlaybackState:
        if self.ended:
            status = PlaybackStatus.Ended
        elif self.seeking:  # "performing a prerequisite operation" (the protocol): reaching the target
            status = PlaybackStatus.Buffering
        else:
            status = PlaybackStatus.Playing if self.playing else PlaybackStatus.Paused
        return PlaybackState(
            status=status,
            current_time=self.position(),
            playback_speed=self.speed,
            did_seek=did_seek,
            request_id=request_id,
        )


class PlaybackListener(ServerListener):
    """Foxglove's playback bar → :class:`Playback`.

    The answer to a request is returned to foxglove-sdk, which sends it with the request's id once the
    callback returns (a request answered otherwise gets an error status).  So that it reaches the client
    before any later state of the replay (reaching a seek's target, the end), the replay holds its own
    states until :data:`ANSWER_GRACE_S` after an answer (:meth:`_BarDriven._broadcast_state`): sent
    at once, a replay that reached the target at once had already told the client it was playing,
    which the answer's Buffering then overrode, and the bar stayed on Buffering."""

    def __init__(self, playback: Playback) -> None:
        self.playback = playback

    def on_playback_control_request(self, request) -> PlaybackState:
        seek = request.seek_time
        with self.playback.cond:
            self.playback.control(request.playback_command == PlaybackCommand.Play, request.playback_speed, seek)
            self.playback.answered_at = time.monotonic()
            return self.playback.state(did_seek=seek is not None, request_id=request.request_id)


class _BarDriven(ABC):
    """The loop of a replay driven from the playback bar; subclasses say how a message is released."""

    def __init__(self, plan: ReplayPlan, playback: Playback, stop: threading.Event, server: Any) -> None:
        self.plan, self.playback, self.stop, self.server = plan, playback, stop, server
        self._time_due = 0.0

    def run(self) -> ReplayStats:
        """Replay until ``stop``: to the end (then wait for a seek), again from each seek's target."""
        stats = ReplayStats()
        target = self.playback.start_ns
        while not self.stop.is_set():
            stats.report = ReadReport(self.plan.path)
            if self._play_from(target, stats):
                self._wait_at_end()
            taken = self.playback.take_seek()
            target = target if taken is None else taken
        self.close()
        return stats

    def _play_from(self, target: int, stats: ReplayStats) -> bool:
        """Release the messages from ``target`` on the playback clock (those before it that :meth:`_skip`
        keeps, as fast as they go); False when a seek (or stop) came first."""
        for i, (key, rm) in enumerate(self.plan.messages(stats.report)):
            if self._skip(i, rm, target):
                continue
            paced = rm.log_time_ns >= target
            if paced:
                if self._arrive():  # the bar plays (or holds) from the target now
                    self._broadcast_state()
                if not self.playback.wait_for(rm.log_time_ns, self.stop):
                    return False
            elif self.stop.is_set() or self.playback.seek_to is not None:
                return False
            self._release(i, key, rm, stats)
            if paced and time.monotonic() >= self._time_due:
                self.server.broadcast_time(rm.log_time_ns)
                self._time_due = time.monotonic() + TIME_EVERY_S
        return True

    def _broadcast_state(self) -> None:
        """Send the playback's state now, after the answer to the bar's last request (:class:`PlaybackListener`)."""
        with self.playback.cond:
            while (wait := self.playback.answered_at + ANSWER_GRACE_S - time.monotonic()) > 0:
                self.playback.cond.wait(wait)  # a request answered meanwhile moves the time on
            self.server.broadcast_playback_state(self.playback.state())

    def _arrive(self) -> bool:
        """At the seek target, if seeking: the bar runs on from it; True if it was seeking."""
        return self.playback.seeking and self.playback.arrived(self._published())

    def _published(self) -> dict[str, int]:
        """Topic key → the last sequence number the graph published (none known in a timed replay)."""
        return {}

    def _wait_at_end(self) -> None:
        self._arrive()  # a seek past the last message
        with self.playback.cond:
            if self.playback.seek_to is not None:  # a seek came on the way to the end: take it instead
                return
            self.playback.ended, self.playback.next_ns = True, self.playback.end_ns
        self._broadcast_state()
        with self.playback.cond:  # the end: wait for a seek back (or stop)
            while self.playback.seek_to is None and not self.stop.is_set():
                self.playback.cond.wait(0.1)

    @abstractmethod
    def _skip(self, index: int, rm: RecordedMessage, target: int) -> bool:
        """Whether the ``index``-th message is not released in a pass from ``target``."""

    @abstractmethod
    def _release(self, index: int, key: str, rm: RecordedMessage, stats: ReplayStats) -> None:
        """Publish the message (and, in lock-step, wait until the graph handled it)."""

    @abstractmethod
    def close(self) -> None:
        """Undeclare the publishers."""


class ControlledReplayer(_BarDriven):
    """Publish a recording on :class:`Playback`'s clock until its end (then wait for a seek) or ``stop``."""

    def __init__(self, session: Any, plan: ReplayPlan, playback: Playback, stop: threading.Event, server: Any) -> None:
        super().__init__(plan, playback, stop, server)
        self.pubs = _Publishers(session)

    def _skip(self, index: int, rm: RecordedMessage, target: int) -> bool:
        return rm.log_time_ns < target

    def _release(self, index: int, key: str, rm: RecordedMessage, stats: ReplayStats) -> None:
        payload, att = rm.wire()
        self.pubs[key].put(payload, attachment=att)
        stats.published[key] += 1

    def close(self) -> None:
        self.pubs.close()


class ControlledLockstep(_BarDriven):
    """Release a lock-step replay's messages on :class:`Playback`'s clock (see the module docstring).

    ``restart_graph()`` starts the graph's nodes afresh; ``changes`` (:class:`.param_replay.RecordedChanges`)
    are applied again from the first after each restart.
    """

    def __init__(
        self,
        lockstep: LockstepReplayer,
        plan: ReplayPlan,
        playback: Playback,
        stop: threading.Event,
        server: Any,
        restart_graph: Callable[[], None],
        changes: Any = None,
        ready_timeout_s: float = 30.0,
    ) -> None:
        super().__init__(plan, playback, stop, server)
        self.lockstep, self.restart_graph, self.changes = lockstep, restart_graph, changes
        self.ready_timeout_s = ready_timeout_s
        self.released = 0  # messages the graph has handled since its start
        self.position: int | None = None  # the log time of the last of them

    def _play_from(self, target: int, stats: ReplayStats) -> bool:
        if self.position is not None and target <= self.position:
            began = time.monotonic()
            self.lockstep.rewind(self.restart_graph, self.ready_timeout_s)
            if self.changes is not None:
                self.changes.rewind()
            self.released, self.position = 0, None
            log.info(
                "seek back to %.3fs: the graph's nodes started afresh in %.1fs; replaying from the start up to it",
                (target - self.playback.start_ns) / 1e9,
                time.monotonic() - began,
            )
        return super()._play_from(target, stats)

    def _skip(self, index: int, rm: RecordedMessage, target: int) -> bool:
        return index < self.released

    def _published(self) -> dict[str, int]:
        return self.lockstep.published()

    def _release(self, index: int, key: str, rm: RecordedMessage, stats: ReplayStats) -> None:
        self.lockstep.step(key, rm, stats, self.changes)
        self.released, self.position = index + 1, rm.log_time_ns

    def close(self) -> None:
        self.lockstep.close()
