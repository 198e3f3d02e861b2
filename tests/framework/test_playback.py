"""The playback bar's clock (framework/recorder/playback.py): what Foxglove is told and shown around a seek."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest

from handflow.framework.files.mcap_reader import RecordedMessage
from handflow.framework.recorder.playback import Playback, _BarDriven

PlaybackStatus = pytest.importorskip("foxglove.websocket").PlaybackStatus

S = 10**9


def test_a_seek_buffers_at_the_target_hides_the_way_there_and_plays_on_from_it():
    playback = Playback(0, 100 * S)
    playback.control(play=True, speed=2.0, seek_ns=40 * S)
    time.sleep(0.05)
    state = playback.state(did_seek=True)
    assert (state.status, state.current_time, state.did_seek) == (PlaybackStatus.Buffering, 40 * S, True)
    assert not playback.shows("handflow/g/n/out", 1_000)  # nothing while the replay reaches the target

    assert not playback.arrived({"handflow/g/n/out": 3})  # a pass started before the seek never arrives
    assert playback.take_seek() == 40 * S and playback.take_seek() is None  # the replay takes the seek
    assert playback.arrived({"handflow/g/n/out": 7})
    assert not playback.arrived({})  # once per seek
    assert not playback.shows("handflow/g/n/out", 7)  # published on the way, delivered late
    assert playback.shows("handflow/g/n/out", 8) and playback.shows("handflow/g/other/out", 1)
    assert playback.state().status == PlaybackStatus.Playing


def test_the_position_never_runs_ahead_of_the_message_waited_for():
    playback = Playback(0, 100 * S, speed=1000.0)
    assert playback.wait_for(5 * S, threading.Event())  # due after 5 ms at this speed
    time.sleep(0.05)  # 50 s of the recording at this speed, but the graph still handles that message
    assert playback.position() == 5 * S
    playback.control(play=False, speed=1000.0, seek_ns=None)
    assert playback.state().status == PlaybackStatus.Paused and playback.position() == 5 * S


class _Plan:
    """Messages on one topic, one a second; the fake graph publishes output number n for the n-th."""

    path = Path("fake.mcap")

    def messages(self, report=None):
        for i in range(20):
            yield "handflow/g/src/out", RecordedMessage("handflow/g/src/out", "Msg", b"", i * S, i * S, i)


class _Driven(_BarDriven):
    """A lock-step pass over :class:`_Plan`: a seek at 10 s comes while message 3 is being released
    (the graph handling it), not while the replay waits for the clock."""

    def __init__(self, playback: Playback, stop: threading.Event) -> None:
        super().__init__(_Plan(), playback, stop, self)
        self.events: list[tuple] = []
        self.released = 0

    def broadcast_playback_state(self, state) -> None:  # the server
        self.events.append(("state", state.status, state.current_time))
        if state.status == PlaybackStatus.Ended:
            self.stop.set()

    def broadcast_time(self, t_ns: int) -> None:
        pass

    def _skip(self, index, rm, target) -> bool:
        return index < self.released

    def _release(self, index, key, rm, stats) -> None:
        if index == 3:
            self.playback.control(play=True, speed=1000.0, seek_ns=10 * S)  # Foxglove's request meanwhile
        self.events.append(("release", index, self.playback.seeking))
        self.released = index + 1

    def _published(self) -> dict[str, int]:
        return {"handflow/g/n/labels": self.released}

    def close(self) -> None:
        pass


def test_a_seek_that_comes_while_a_message_is_released_is_reached_at_its_target_only():
    """The pass started before the seek must not take the next message for the target: the outputs of
    messages 4–9 (computed on the way, delivered whenever) stay hidden, and the bar plays on from the
    target only once message 10 is next."""
    playback, stop = Playback(0, 19 * S, speed=1000.0), threading.Event()
    driven = _Driven(playback, stop)
    runner = threading.Thread(target=driven.run, daemon=True)
    runner.start()
    runner.join(10)
    assert not runner.is_alive()
    released = [e[1] for e in driven.events if e[0] == "release"]
    assert released == list(range(20))
    playing = driven.events.index(("state", PlaybackStatus.Playing, 10 * S))
    assert [e for e in driven.events if e[0] == "state"] == [
        ("state", PlaybackStatus.Playing, 10 * S),
        ("state", PlaybackStatus.Ended, 19 * S),
    ]
    assert driven.events[playing - 1] == ("release", 9, True) and driven.events[playing + 1][:2] == ("release", 10)
    assert [n for n in range(1, 21) if playback.shows("handflow/g/n/labels", n)] == list(range(11, 21))
