"""Counting, logging and reporting payloads a node's input dropped (docs/robustness.md).

The runner drops a payload that does not decode to a valid message, is not the input port's message
type, or makes the node's ``on_message`` raise :class:`handflow.framework.messages.MessageError`.
:class:`DropLedger` counts drops per input, logs the first drop of an input at once and then at most
one summary line per input every ``log_interval_s``, and turns the drops since the last report into
``dropped`` :class:`handflow.framework.messages.RuntimeEvent` messages (one per input and report),
which the runner publishes on ``handflow/<graph>/_runtime/events`` (recorded, shown by ``monitor``).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

from ..messages import RuntimeEvent

LOG_INTERVAL_S = 5.0


@dataclass
class _InputDrops:
    topic: str
    total: int = 0
    unreported: int = 0
    unlogged: int = 0
    last_reason: str = ""
    next_log: float = 0.0


class DropLedger:
    """Drops of one node's inputs: ``note`` from the message path, ``report`` from the main loop."""

    def __init__(
        self, node_id: str, topics: dict[str, str], log: logging.Logger, log_interval_s: float = LOG_INTERVAL_S
    ):
        self.node_id = node_id
        self.log = log
        self.log_interval_s = log_interval_s
        self._inputs = {port: _InputDrops(topic) for port, topic in topics.items()}

    def note(self, port: str, reason: str) -> None:
        d = self._inputs[port]
        d.total += 1
        d.unreported += 1
        d.last_reason = reason
        now = time.monotonic()
        if now >= d.next_log:
            more = f" ({d.unlogged} more since the last report)" if d.unlogged else ""
            self.log.warning("dropped a payload on input '%s' from %s%s: %s", port, d.topic, more, reason)
            d.unlogged = 0
            d.next_log = now + self.log_interval_s
        else:
            d.unlogged += 1

    def counts(self) -> dict[str, int]:
        """Total drops per input port."""
        return {port: d.total for port, d in self._inputs.items()}

    def report(self) -> list[RuntimeEvent]:
        """One ``dropped`` event per input that dropped payloads since the last report."""
        events = []
        for d in self._inputs.values():
            if d.unreported:
                events.append(
                    RuntimeEvent(
                        kind="dropped", node=self.node_id, topic=d.topic, count=d.unreported, detail=d.last_reason[:300]
                    )
                )
                d.unreported = 0
        return events
