"""Which path a node process's topics take: iceoryx2 on this graph host, Zenoh to everyone else (docs/shared_memory.md).

With ``transport: {local: iceoryx2}`` (the default) a node process opens a
:class:`~handflow.framework.network.local_transport.LocalTransport` for its launcher's run.

* An input whose source node belongs to the same graph host (the same ``host:`` field, so the
  same ``handflow run --host``) is read from iceoryx2 only, never subscribed on Zenoh: local
  subscribers are no Zenoh matches and get each message once.  Sources of other hosts, and topics
  fed from outside the graph (replay, external publishers), are read from Zenoh.
* An :class:`OutputPort` sends each message to iceoryx2, and over Zenoh only while a Zenoh
  subscriber matches (a node of another host, the recorder, the monitor, the Foxglove bridge, a
  bare Zenoh peer); :meth:`OutputPort.send` says which paths the message took (:data:`ZENOH`,
  :data:`LOCAL`), which the heartbeat reports as ``path.<port>`` for ``handflow monitor``.

With ``local: zenoh``, or when iceoryx2 is not usable here (one notice), everything is Zenoh as before.
"""

from __future__ import annotations

import dataclasses
import struct
from collections.abc import Callable
from typing import Any

import numpy as np

from .. import wire
from ..graphs.model import Graph
from ..messages import CompressedImage, Image, Message
from ..network import local_transport
from ..network.local_transport import LOCAL, ZENOH, LocalPublisher, LocalTransport


def run_of(hub: str) -> str:
    """The launcher run a node process belongs to: its hub's port (unique on this machine while it runs)."""
    return "run" + hub.rsplit(":", 1)[-1]


def open_for(graph: Graph, hub: str, node_ids: list[str]) -> LocalTransport | None:
    """The process's local transport, or ``None`` for Zenoh only (``transport.local: zenoh`` or unusable)."""
    if graph.spec.transport.local != "iceoryx2":
        return None
    return local_transport.open_local(run_of(hub), f"handflow/{graph.name}/{','.join(node_ids)}")


BULKY = (Image, CompressedImage)
"""Message types whose topics get the small sample budgets of the local transport (megabytes each)."""


def is_bulky(cls: type[Message]) -> bool:
    return issubclass(cls, BULKY)


def local_sources(graph: Graph, node_ids: list[str]) -> set[str]:
    """The graph's nodes on the graph host of ``node_ids`` (the nodes of one process share a host)."""
    host = graph.nodes[node_ids[0]].spec.host
    return {ns.id for ns in graph.spec.nodes if ns.host == host}


class OutputPort:
    """One output topic: Zenoh publisher plus, on the local transport, an iceoryx2 publisher."""

    def __init__(self, zenoh_pub: Any, local: LocalPublisher | None) -> None:
        self.zenoh, self.local = zenoh_pub, local  # zenoh_pub None: iceoryx2 only (benchmarks/local_transport.py)

    def _to_zenoh(self) -> bool:
        return self.zenoh is not None and (self.local is None or self.zenoh.matching_status.matching)

    def allocate(self, nbytes: int) -> np.ndarray:
        """``ctx.allocate``: on the local transport an array inside a loaned sample (the image is then
        published without copying its pixels), else (or when none is free) an ordinary array."""
        arr = self.local.loan(nbytes) if self.local is not None else None
        return np.empty(nbytes, np.uint8) if arr is None else arr

    def publish(self, msg: Message, body: bytes | memoryview | None, wrap: Callable[[bytes], Any]) -> tuple[int, bool]:
        """Encode and :meth:`send` ``msg`` (its header filled in); ``body``: the CDR it was received
        as, when it is forwarded unchanged (:mod:`.forwarding`).  An ``Image`` whose data came from
        :meth:`allocate` is sent in place."""
        if isinstance(msg, Image) and self.local is not None and self.local.lent(msg.data):
            sent = self._send_lent(msg, wrap)
            if sent is not None:
                return sent
        payload, att = (body is not None and wire.repack(msg, body)) or wire.pack(msg)
        return self.send(payload, att, wrap)

    def _send_lent(self, msg: Image, wrap: Callable[[bytes], Any]) -> tuple[int, bool] | None:
        """The image's other fields encoded (data last in its CDR), its pixels already in the sample."""
        head, att = wire.pack(dataclasses.replace(msg, data=b""))
        prefix = head[:-4] + struct.pack("<I", len(msg.data))  # the data's length, then the data
        sent = self.local.send_loaned(msg.data, prefix, att, self._to_zenoh())
        if sent is None:
            return None
        receivers, payload = sent
        path, pooled = LOCAL if receivers else 0, False
        if payload is not None:
            data = wrap(payload)
            self.zenoh.put(data, attachment=att)
            path, pooled = path | ZENOH, data is not payload
        return path, pooled

    def send(self, payload: bytes | memoryview, att: bytes, wrap: Callable[[bytes], Any]) -> tuple[int, bool]:
        """Send one message; ``wrap`` prepares the Zenoh payload (the shared-memory pool).  Returns the
        paths taken and whether the Zenoh payload came from the pool."""
        path, pooled = 0, False
        if self.local is not None and self.local.send(payload, att):
            path |= LOCAL
        if self._to_zenoh():
            data = bytes(payload) if isinstance(payload, memoryview) else payload
            sent = wrap(data)
            self.zenoh.put(sent, attachment=att)
            path |= ZENOH
            pooled = sent is not data
        return path, pooled
