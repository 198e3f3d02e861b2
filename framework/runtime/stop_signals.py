"""Ctrl-C and SIGTERM as a request, not an exception: while a :class:`StopSignals` block runs, SIGINT
and SIGTERM set its event, and the command stops in order at its next check.  Installed at the very
start of ``handflow run``, no ``KeyboardInterrupt`` can cut the start-up between opening a Zenoh
session and registering its close, so every path closes what it opened (docs/reliability.md)."""

from __future__ import annotations

import signal
import threading

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopSignals:
    """``with StopSignals() as stop: … if stop.is_set(): …``; the previous handlers come back at the end
    (outside the main thread, where handlers cannot be installed, it is a plain event)."""

    def __init__(self) -> None:
        self.event = threading.Event()
        self._previous: dict[int, object] = {}

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is threading.main_thread():
            self._previous = {s: signal.signal(s, self._request) for s in SIGNALS}
        return self

    def __exit__(self, *exc: object) -> None:
        for s, handler in self._previous.items():
            signal.signal(s, handler)
        self._previous = {}

    def _request(self, signum: int, frame: object) -> None:
        self.event.set()

    def is_set(self) -> bool:
        return self.event.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        """Until a stop is asked for (True) or ``timeout`` passes (False)."""
        return self.event.wait(timeout)
