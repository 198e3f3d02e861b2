"""A real Foxglove WebSocket client's connection (the ``foxglove.websocket.v1`` protocol over ``websockets``)."""

from __future__ import annotations

import time

from websockets.sync.client import connect


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
