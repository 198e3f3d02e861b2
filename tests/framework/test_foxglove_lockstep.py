"""A lock-step replay driven from Foxglove's playback bar (docs/recording.md, "Replay from Foxglove's playback
bar"): a real ``foxglove.sdk.v1`` client pauses, changes the speed and seeks back a tuned recording
replayed into the flagship's segmenter; each request is answered with a playback state carrying its id,
no status of level warning or error arrives and the terminal shows no ERROR line; after the seek back,
the labels it receives equal those of an uninterrupted lock-step replay (the recorded parameter changes
applied again in order)."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from handflow.framework import keys
from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.files.mcap_writer import McapWriter
from handflow.framework.graphs.model import load_graph
from handflow.framework.messages import Header, ParamChange
from handflow.framework.observe.foxglove_layout import carried, layout_for
from tests.foxglove_client import FoxgloveClient, handflow_with_foxglove, playback_request, playback_state

pytest.importorskip("foxglove")
pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]
GRAPH = REPO / "configs" / "demo_segment_only.yaml"  # the segmenter: its labels depend on the frames before
JOINTS = "handflow/gestures/shadow/joints"
LABELS = "/handflow/demo_segment_only/segmenter/labels"
FRAMES, MIDDLE = 400, 200  # 10 s of the shipped gesture recording; the seek goes back to frame 200
CHANGES = {100: 4.0, 300: 0.5}  # background_factor set while it was recorded, at these frames
PLAY, PAUSE, PLAYING, PAUSED, BUFFERING, ENDED = 0, 1, 0, 1, 2, 3  # request commands, state statuses


def _take(path: Path) -> list[int]:
    """The first FRAMES joint frames of the gesture recording, tuned at frames 100 and 300 (CHANGES); their
    stamps (= log times)."""
    stamps = []
    with McapWriter(path) as writer:
        for i, rm in enumerate(iter_recording(REPO / "recordings" / "gestures.mcap", [JOINTS])):
            if i == FRAMES:
                break
            if i in CHANGES:
                change = ParamChange(node="segmenter", key="background_factor", value=json.dumps(CHANGES[i]))
                change.header = Header("segmenter", i, rm.publish_time_ns)
                writer.write(keys.params_key("gestures"), change, log_time_ns=rm.publish_time_ns)
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


def _seek(fox: FoxgloveClient, speed: float, seek_ns: int, request: str) -> tuple[list[dict], list[bytes], float]:
    """Seek and play: the playback states from the answer until the replay ends, the label payloads received
    once the bar plays from the target (until shortly after the end), and how long after the request the first
    came."""
    fox.ws.send(playback_request(PLAY, speed, seek_ns, request))
    sent, states, labels, first = time.monotonic(), [], [], 0.0
    while not states or states[-1]["status"] != ENDED:
        frame = fox.recv(timeout=60)
        if isinstance(frame, bytes) and frame[0] == 5:
            states.append(fox.states[-1])
        elif isinstance(frame, bytes) and frame[0] == 1 and states:  # before the answer: sent before the seek
            assert len(states) == 2, "a label before the bar played from the target"  # the answer, then playing
            labels.append(frame[13:])
            first = first or time.monotonic() - sent
    return states, labels + _received(fox, 0.5), first  # the last labels may follow the end's state


def test_lockstep_replay_follows_the_playback_bar_and_a_seek_back_gives_the_uninterrupted_labels(tmp_path):
    stamps = _take(tmp_path / "take.mcap")
    env = dict(os.environ, HANDFLOW_RUN_DIR=str(tmp_path / "runs"))
    args = ["replay", str(tmp_path / "take.mcap"), "--into", str(GRAPH), "--lockstep"]
    reference = subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", *args, "--record", str(tmp_path / "uninterrupted.mcap")],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )
    assert reference.returncode == 0, reference.stderr
    assert "applying 2 recorded parameter change(s)" in reference.stderr  # they change 103 of the last 200 labels
    uninterrupted = [rm.data for rm in iter_recording(tmp_path / "uninterrupted.mcap", ["segmenter/labels"])]
    assert [_stamp(cdr) for cdr in uninterrupted] == stamps  # one label per frame, stamped with it

    replay, port = handflow_with_foxglove(args, env, tmp_path)
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
            ahead = next(i for i, t in enumerate(stamps) if t > fast[-1] + 10**9)  # a second ahead
            forward, after_forward, _ = _seek(fox, 2.0, stamps[ahead], "ahead")
            back, after_back, cost = _seek(fox, 4.0, stamps[MIDDLE], "back")  # from the end
            fox.binary(opcode=5, seconds=0.5)  # a late status would come now
    finally:
        replay.send_signal(signal.SIGINT)
        _, err = replay.communicate(timeout=60)
    assert replay.returncode == 0, err
    assert fox.problems() == []  # no "Server did not send playback state ..."
    assert " ERROR " not in err, err
    # the flagship layout written for this graph (`handflow layout`): every topic it names that the graph
    # carries reached the client, so its joint, label and event panels show the replay
    wanted = {f"/handflow/demo_segment_only/{t}" for t in carried(load_graph(GRAPH))}
    named = set(re.findall(r"/handflow/demo_segment_only/\w+/\w+", layout_for("demo_segment_only")))
    assert len(named & wanted) == 3 and named & wanted <= fox.topics, fox.topics
    answered = [st["id"] for st in fox.states if st["id"]]
    assert answered == [b"pause", b"slow", b"fast", b"ahead", b"back"]  # one answer each, in order

    assert (paused["status"], paused["did_seek"], paused["id"]) == (PAUSED, False, b"pause")
    assert len(held) <= 1  # paused: no label advances (one in flight at most)
    assert 0.5 <= (slow[-1] - slow[0]) / 1e9 <= 1.0  # 1.5 s at half speed: 0.75 s of the recording
    assert (fast[-1] - fast[0]) / 1e9 >= 4 * (slow[-1] - slow[0]) / 1e9 * 0.6  # four times faster
    assert ahead < FRAMES - 20
    for states, target, request in ((forward, ahead, b"ahead"), (back, MIDDLE, b"back")):
        # the answer: at the target, reaching it; then playing from it; then the end
        assert [(st["status"], st["did_seek"], st["time"], st["id"]) for st in states[:2]] == [
            (BUFFERING, True, stamps[target], request),
            (PLAYING, False, stamps[target], b""),
        ]
        assert [st["status"] for st in states[2:]] == [ENDED]
    # what the graph handled to reach the target is not shown; from the target on, the uninterrupted labels
    assert [_stamp(cdr) for cdr in after_forward] == stamps[ahead:]
    assert after_forward == uninterrupted[ahead:]
    assert [_stamp(cdr) for cdr in after_back] == stamps[MIDDLE:]
    assert after_back == uninterrupted[MIDDLE:]
    assert cost < 15  # restarting the nodes and replaying 200 frames: 1.5-2 s here
