"""A real Foxglove WebSocket client (a ``foxglove.sdk.v1`` client over ``websockets``, the subprotocol
foxglove-sdk's server speaks): its connection, the Foxglove app's side of the protocol, and the binary
frames of the playback bar."""

from __future__ import annotations

import json
import re
import struct
import subprocess
import sys
import time
from pathlib import Path

from websockets.sync.client import connect

from handflow.framework.network.sessions import free_tcp_port

# foxglove-sdk advertises a channel that appears while a client is connected just before it records the channel
# for that client, so a fast subscription can be refused with this status (docs/foxglove.md, "Topics")
UNKNOWN_CHANNEL = re.compile(r"Unknown channel ID: (\d+)")
RESUBSCRIPTIONS = 5  # per channel, 0.1 s apart: the server records the channel right after advertising it


def handflow_with_foxglove(args: list[str], env: dict[str, str], cwd: Path) -> tuple[subprocess.Popen, int]:
    """``handflow ARGS --foxglove PORT`` on a free port, its stderr piped: the process and the port."""
    port = free_tcp_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", *args, "--foxglove", str(port)],
        cwd=cwd,
        env=env,
        stderr=subprocess.PIPE,
        text=True,
    )
    return proc, port


def connect_foxglove(port: int, timeout: float):
    """A client connection to ``ws://127.0.0.1:PORT``, retried until the server listens or ``timeout`` passes."""
    deadline = time.time() + timeout
    while True:
        try:
            return connect(
                f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"], open_timeout=2
            )
        except OSError:
            if time.time() > deadline:
                raise
            time.sleep(0.3)


class FoxgloveClient:
    """The Foxglove app's side of the protocol: JSON requests, replies picked by their ``op``.  Every status
    message, playback state and advertised topic received on the way is kept (``statuses``, ``states``,
    ``topics``).  A subscription refused for a channel the server has just advertised is sent again, as
    docs/foxglove.md tells programmatic clients to do; the refusals are kept in ``resubscribed`` (channel ids),
    not in ``statuses``."""

    def __init__(self, port: int, timeout: float = 30.0) -> None:
        self.ws = connect_foxglove(port, timeout)
        self.statuses: list[dict] = []
        self.states: list[dict] = []
        self.topics: set[str] = set()
        self.resubscribed: list[int] = []
        self._subscriptions: dict[int, list[dict]] = {}  # channel id → the subscriptions sent for it

    def recv(self, timeout: float) -> str | bytes:
        """The next frame (``TimeoutError`` after ``timeout``), noting statuses and playback states."""
        frame = self.ws.recv(timeout=timeout)
        if isinstance(frame, str) and (msg := json.loads(frame)).get("op") == "status":
            if not self._subscribe_again(msg):
                self.statuses.append(msg)
        elif isinstance(frame, str) and msg.get("op") == "advertise":
            self.topics |= {c["topic"] for c in msg["channels"]}
        elif isinstance(frame, bytes) and frame[0] == 5:
            self.states.append(playback_state(frame))
        return frame

    def _subscribe_again(self, status: dict) -> bool:
        """Whether ``status`` refused a subscription of ours that was sent again (at most
        :data:`RESUBSCRIPTIONS` times per channel)."""
        unknown = UNKNOWN_CHANNEL.search(status.get("message", ""))
        channel = int(unknown.group(1)) if unknown else None
        if channel not in self._subscriptions or self.resubscribed.count(channel) >= RESUBSCRIPTIONS:
            return False
        self.resubscribed.append(channel)
        time.sleep(0.1)
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": self._subscriptions[channel]}))
        return True

    def problems(self) -> list[dict]:
        """The status messages of level warning (1) or error (2) received so far."""
        return [s for s in self.statuses if s.get("level", 0) >= 1]

    def __enter__(self) -> FoxgloveClient:
        self.ws.__enter__()
        self.server_info = self.next("serverInfo")
        return self

    def __exit__(self, *exc) -> None:
        self.ws.__exit__(*exc)

    def send(self, **msg) -> None:
        if msg.get("op") == "subscribe":
            for sub in msg["subscriptions"]:
                self._subscriptions.setdefault(sub["channelId"], []).append(sub)
        self.ws.send(json.dumps(msg))

    def next(self, op: str, timeout: float = 15.0, **match) -> dict:
        deadline = time.time() + timeout
        while time.time() < deadline:
            try:
                frame = self.recv(timeout=1)
            except TimeoutError:
                continue
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg.get("op") == op and all(msg.get(k) == v for k, v in match.items()):
                    return msg
        raise AssertionError(f"no {op} {match} within {timeout}s")

    def binary(self, opcode: int, seconds: float) -> list[bytes]:
        """The binary frames with ``opcode`` received within ``seconds`` (message data 1, playback state 5)."""
        frames, deadline = [], time.time() + seconds
        while (left := deadline - time.time()) > 0:
            try:
                frame = self.recv(timeout=left)
            except TimeoutError:
                break
            if isinstance(frame, bytes) and frame[0] == opcode:
                frames.append(frame)
        return frames

    def values(self, **request) -> dict[str, object]:
        msg = self.next("parameterValues", id=request.get("id"))
        return {p["name"]: p.get("value") for p in msg["parameters"]}


def playback_request(command: int, speed: float, seek_ns: int | None, request_id: str) -> bytes:
    """Foxglove's binary PlaybackControlRequest (opcode 3): command (0 play, 1 pause), speed, seek, id."""
    head = struct.pack("<BBfB", 3, command, speed, seek_ns is not None) + struct.pack("<Q", seek_ns or 0)
    return head + struct.pack("<I", len(request_id)) + request_id.encode()


def playback_state(frame: bytes) -> dict:
    """The server's binary PlaybackState (opcode 5)."""
    status, current, speed, did_seek, n = struct.unpack_from("<BQfBI", frame, 1)
    return {"status": status, "time": current, "speed": speed, "did_seek": bool(did_seek), "id": frame[19 : 19 + n]}
