"""Large payloads between node processes on one host through Zenoh shared memory (docs/shared_memory.md).

Each node process owns one :class:`SharedPayloads` pool (a Zenoh ``ShmProvider`` of
:data:`POOL_BYTES`, created on first use).  A payload of at least :data:`THRESHOLD` bytes is copied
once into a buffer of the pool and published from there: a subscriber on this host receives a
reference to the buffer instead of the bytes, a peer elsewhere (or one with shared memory off)
receives the bytes over the network as before.  Zenoh frees a buffer when the last process holding
it drops it; the pool collects freed buffers when it runs short (:data:`_POLICY`).  When the pool
is exhausted, or the installed eclipse-zenoh has no shared-memory API (before 1.6), a payload takes
the network path: nothing fails.
"""

from __future__ import annotations

import json
import logging

import zenoh

try:
    from zenoh import shm as _zshm
except ImportError:  # eclipse-zenoh without the Python shared-memory API
    _zshm = None

log = logging.getLogger("handflow.shm")

THRESHOLD = 64 * 1024
"""Payloads of at least this many bytes are published from shared memory (measured in docs/shared_memory.md)."""
POOL_BYTES = 64 << 20
"""Shared memory per node process: ten 1080p RGB frames in flight."""
_POLICY = None if _zshm is None else _zshm.GarbageCollect(_zshm.JustAlloc(), _zshm.Defragment())


def configure(conf: zenoh.Config, enabled: bool) -> None:
    """Turn Zenoh's shared-memory transport on or off in a session configuration."""
    conf.insert_json5("transport/shared_memory/enabled", json.dumps(enabled))


def available() -> bool:
    """Whether the installed eclipse-zenoh has the Python shared-memory API."""
    return _zshm is not None


def via_shm(payload: zenoh.ZBytes) -> bool:
    """Whether a received payload is a shared-memory buffer (the monitor's ``shm`` column)."""
    return _zshm is not None and payload.as_shm() is not None


class SharedPayloads:
    """The node process's pool; :meth:`wrap` turns a payload into what ``Publisher.put`` sends."""

    def __init__(self, enabled: bool, pool_bytes: int = POOL_BYTES) -> None:
        self.enabled = enabled and _zshm is not None
        if enabled and _zshm is None:
            log.info("this eclipse-zenoh has no shared-memory API; large payloads take the network path")
        self._pool_bytes = pool_bytes
        self._provider = None
        self.sent = 0  # payloads published from shared memory
        self.fallbacks = 0  # large payloads sent as bytes because the pool was exhausted

    def wrap(self, payload: bytes | bytearray) -> bytes | bytearray | zenoh.ZBytes:
        n = len(payload)
        if not self.enabled or n < THRESHOLD:
            return payload
        try:
            if self._provider is None:
                self._provider = _zshm.ShmProvider.default_backend(self._pool_bytes)
            buf = self._provider.alloc(n, _POLICY)
        except zenoh.ZError as exc:
            self.fallbacks += 1
            if self.fallbacks == 1 or self.fallbacks % 1000 == 0:
                log.warning("shared memory unavailable (%s); %d payload(s) sent over the network", exc, self.fallbacks)
            return payload
        buf[0:n] = payload
        self.sent += 1
        return zenoh.ZBytes(buf)
