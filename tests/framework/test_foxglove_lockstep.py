"""A lock-step replay driven from Foxglove's playback bar (docs/recording.md, "Replay from Foxglove's playback
bar"): a real ``foxglove.websocket.v1`` client pauses, changes the speed and seeks back into the flagship's
segmenter; after the seek back, the labels it receives equal those of an uninterrupted lock-step replay."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.files.mcap_writer import McapWriter
from handflow.framework.messages import Header
from handflow.framework.network.sessions import free_tcp_port
from tests.foxglove_client import FoxgloveClient, playback_request, playback_state

pytest.importorskip("foxglove")
pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]
GRAPH = REPO / "configs" / "demo_segment_only.yaml"  # the segmenter: its labels depend on the frames before
JOINTS = "handflow/gestures/shadow/joints"
LABELS = "/handflow/demo_segment_only/segmenter/labels"
FRAMES, MIDDLE = 400, 200  # 10 s of the shipped gesture recording; the seek goes back to frame 200
PLAY, PAUSE, PLAYING, PAUSED, ENDED = 0, 1, 0, 1, 3  # request commands, state statuses


def _take(path: Path) -> list[int]:
    """The first FRAMES joint frames of the gesture recording; their stamps (= log times)."""
    stamps = []
    with McapWriter(path) as writer:
        for i, rm in enumerate(iter_recording(REPO / "recordings" / "gestures.mcap", [JOINTS])):
            if i == FRAMES:
                break
            msg = rm.decode()
            msg.header = Header("shadow", i + 1, rm.publish_time_ns)
            writer.write(JOINTS, msg, log_time_ns=rm.publish_time_ns)
            stamps.append(rm.publish_time_ns)
    return stamps


def _received(fox: FoxgloveClient, seconds: float) -> list[bytes]:
    """The payloads of the label messages (binary opcode 1, subscription 1) received within ``seconds``."""
    return [f[13:] for f in fox.binary(opcode=1, seconds=seconds) if int.from_bytes(f[1:5], "little") == 1]


def _stamp(cdr: bytes) -> int:
    """A label's header stamp: the CDR body starts with builtin_interfaces/Time (sec int32, nanosec uint32)."""
    return int.from_bytes(cdr[4:8], "little", signed=True) * 10**9 + int.from_bytes(cdr[8:12], "little")


def _until_ended(fox: FoxgloveClient, timeout: float) -> tuple[list[bytes], float | None]:
    """The label payloads received until the playback state says the replay ended, and when the first came."""
    labels, first, deadline = [], None, time.time() + timeout
    while time.time() < deadline:
        frame = fox.ws.recv(timeout=deadline - time.time())
        if isinstance(frame, bytes) and frame[0] == 1 and int.from_bytes(frame[1:5], "little") == 1:
            labels.append(frame[13:])
            first = first or time.monotonic()
        elif isinstance(frame, bytes) and frame[0] == 5 and playback_state(frame)["status"] == ENDED:
            return labels, first
    raise AssertionError(f"the replay did not end within {timeout}s")


def test_lockstep_replay_follows_the_playback_bar_and_a_seek_back_gives_the_uninterrupted_labels(tmp_path):
    stamps = _take(tmp_path / "take.mcap")
    env = dict(os.environ, HANDFLOW_RUN_DIR=str(tmp_path / "runs"))
    cli = [sys.executable, "-m", "handflow.framework.cli", "replay", str(tmp_path / "take.mcap"), "--into", str(GRAPH)]
    reference = subprocess.run(
        [*cli, "--lockstep", "--record", str(tmp_path / "uninterrupted.mcap")],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )
    assert reference.returncode == 0, reference.stderr
    uninterrupted = [rm.data for rm in iter_recording(tmp_path / "uninterrupted.mcap", ["segmenter/labels"])]
    assert [_stamp(cdr) for cdr in uninterrupted] == stamps  # one label per frame, stamped with it

    port = free_tcp_port()
    replay = subprocess.Popen(
        [*cli, "--lockstep", "--foxglove", str(port)], cwd=tmp_path, env=env, stderr=subprocess.PIPE, text=True
    )
    try:
        with FoxgloveClient(port, timeout=60) as fox:
            assert "playbackControl" in fox.server_info["capabilities"]
            channel = None
            while channel is None:  # advertised with the first label
                advertised = fox.next("advertise", timeout=60)["channels"]
                channel = next((c for c in advertised if c["topic"] == LABELS), None)
            fox.send(op="subscribe", subscriptions=[{"id": 1, "channelId": channel["id"]}])

            fox.ws.send(playback_request(PAUSE, 1.0, None, "pause"))
            paused = playback_state(fox.binary(opcode=5, seconds=0.5)[0])
            held = _received(fox, 1.0)
            fox.ws.send(playback_request(PLAY, 0.5, None, "slow"))
            slow = [_stamp(cdr) for cdr in _received(fox, 1.5)]
            fox.ws.send(playback_request(PLAY, 2.0, None, "fast"))
            fast = [_stamp(cdr) for cdr in _received(fox, 1.5)]
            assert _until_ended(fox, timeout=30)[0]

            fox.ws.send(playback_request(PLAY, 4.0, stamps[MIDDLE], "back"))
            sought = time.monotonic()
            seek = playback_state(fox.binary(opcode=5, seconds=0.2)[0])
            after, first = _until_ended(fox, timeout=60)
    finally:
        replay.send_signal(signal.SIGINT)
        _, err = replay.communicate(timeout=60)
    assert replay.returncode == 0, err

    assert (paused["status"], paused["did_seek"], paused["id"]) == (PAUSED, False, b"pause")
    assert len(held) <= 1  # paused: no label advances (one in flight at most)
    assert 0.5 <= (slow[-1] - slow[0]) / 1e9 <= 1.0  # 1.5 s at half speed: 0.75 s of the recording
    assert (fast[-1] - fast[0]) / 1e9 >= 4 * (slow[-1] - slow[0]) / 1e9 * 0.6  # four times faster
    assert (seek["status"], seek["did_seek"], seek["time"], seek["id"]) == (PLAYING, True, stamps[MIDDLE], b"back")
    # the catch-up from the start is not shown; from the target on, exactly the uninterrupted labels
    assert [_stamp(cdr) for cdr in after] == stamps[MIDDLE:]
    assert after == uninterrupted[MIDDLE:]
    assert first - sought < 15  # restarting the nodes and replaying 200 frames: about 2-3 s here
