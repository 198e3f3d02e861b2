"""A timed replay driven from Foxglove's playback bar: play, pause, seek, speed (docs/recording.md).

:class:`Playback` keeps the replay's position on the recording's clock and maps it to the wall
clock at the chosen speed; :class:`ControlledReplayer` publishes the recording as
:class:`.replay.TimedReplayer` does, but waits on that clock, holds while paused and, after a seek,
starts again from the first message at or after the target (going back reads the file from the
start).  :class:`PlaybackListener` answers Foxglove's PlaybackControl requests.
"""

from __future__ import annotations

import threading
import time
from typing import Any

try:  # the optional extra 'foxglove', 0.30 or newer for PlaybackControl
    from foxglove.websocket import PlaybackCommand, PlaybackState, PlaybackStatus, ServerListener
except ImportError as exc:
    SDK_MISSING: str | None = str(exc)
    ServerListener = object
else:
    SDK_MISSING = None

from ..files.mcap_reader import ReadReport, iter_recording
from .replay import ReplayPlan, ReplayStats, _Publishers

TIME_EVERY_S = 0.1  # how often the playback bar hears the position


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
        self.seek_to: int | None = None
        self._anchor = (time.monotonic(), start_ns)  # wall time ↔ recording time at the last change

    def position(self) -> int:
        """The recording time playing now."""
        wall, rec = self._anchor
        if not self.playing:
            return rec
        return min(self.end_ns, rec + int((time.monotonic() - wall) * 1e9 * self.speed))

    def control(self, play: bool, speed: float, seek_ns: int | None) -> None:
        with self.cond:
            now = self.position() if seek_ns is None else min(max(int(seek_ns), self.start_ns), self.end_ns)
            self.playing = play
            self.speed = speed if speed > 0 else self.speed
            self._anchor = (time.monotonic(), now)
            if seek_ns is not None:
                self.seek_to, self.ended = now, False
            self.cond.notify_all()

    def wait_for(self, log_ns: int, stop: threading.Event) -> bool:
        """Wait until the replay reaches ``log_ns``; False when a seek (or stop) came first."""
        with self.cond:
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
        status = (
            PlaybackStatus.Ended if self.ended else PlaybackStatus.Playing if self.playing else PlaybackStatus.Paused
        )
        return PlaybackState(
            status=status,
            current_time=self.position(),
            playback_speed=self.speed,
            did_seek=did_seek,
            request_id=request_id,
        )


class PlaybackListener(ServerListener):
    """Foxglove's playback bar → :class:`Playback`."""

    def __init__(self, playback: Playback) -> None:
        self.playback = playback

    def on_playback_control_request(self, request) -> PlaybackState:
        seek = request.seek_time
        self.playback.control(request.playback_command == PlaybackCommand.Play, request.playback_speed, seek)
        return self.playback.state(did_seek=seek is not None, request_id=request.request_id)


class ControlledReplayer:
    """Publish a recording on :class:`Playback`'s clock until its end (then wait for a seek) or ``stop``."""

    def __init__(self, session: Any, plan: ReplayPlan, playback: Playback, stop: threading.Event, server: Any) -> None:
        self.plan, self.playback, self.stop, self.server = plan, playback, stop, server
        self.pubs = _Publishers(session)

    def run(self) -> ReplayStats:
        stats = ReplayStats()
        start = self.playback.start_ns
        while not self.stop.is_set():
            stats.report = ReadReport(self.plan.path)
            next_time = 0.0
            for key, rm in self.plan.messages(stats.report):
                if rm.log_time_ns < start:
                    continue  # before the seek target
                if not self.playback.wait_for(rm.log_time_ns, self.stop):
                    break
                payload, att = rm.wire()
                self.pubs[key].put(payload, attachment=att)
                stats.published[key] += 1
                if time.monotonic() >= next_time:
                    self.server.broadcast_time(rm.log_time_ns)
                    next_time = time.monotonic() + TIME_EVERY_S
            else:
                with self.playback.cond:
                    self.playback.ended = True
                self.server.broadcast_playback_state(self.playback.state())
                with self.playback.cond:  # the end: wait for a seek back (or stop)
                    while self.playback.seek_to is None and not self.stop.is_set():
                        self.playback.cond.wait(0.1)
            with self.playback.cond:
                start, self.playback.seek_to = self.playback.seek_to or start, None
        self.pubs.close()
        return stats
