"""The playback bar's clock (framework/recorder/playback.py): what Foxglove is told and shown around a seek."""

from __future__ import annotations

import threading
import time

import pytest

from handflow.framework.recorder.playback import Playback

PlaybackStatus = pytest.importorskip("foxglove.websocket").PlaybackStatus

S = 10**9


def test_a_seek_buffers_at_the_target_hides_the_way_there_and_plays_on_from_it():
    playback = Playback(0, 100 * S)
    playback.control(play=True, speed=2.0, seek_ns=40 * S)
    time.sleep(0.05)
    state = playback.state(did_seek=True)
    assert (state.status, state.current_time, state.did_seek) == (PlaybackStatus.Buffering, 40 * S, True)
    assert not playback.shows("handflow/g/n/out", 1_000)  # nothing while the replay reaches the target

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
