"""The graph's status line (``status:``): one field of one topic in the terminal of ``handflow run``.

A line ``<node>/<port>: <value>`` is logged when the field's value changes, at most once per
``min_interval_s`` (the latest value wins), e.g. the recognised gesture of the demo (docs/pipelines.md).
"""

from __future__ import annotations

import logging
import time
from typing import Any

from .. import keys, wire
from ..graphs.model import StatusSpec
from ..messages import MessageError

log = logging.getLogger("handflow.status")


class StatusLine:
    """Subscribes to the ``status`` topic of a graph and logs its field when it changes."""

    def __init__(self, graph_name: str, spec: StatusSpec) -> None:
        self.spec = spec
        self.key = keys.topic_key(graph_name, *spec.topic.split("/", 1))
        self.shown: Any = None
        self.shown_at: float | None = None
        self._subscriber: Any = None

    def attach(self, session: Any) -> None:
        self._subscriber = session.declare_subscriber(self.key, self._on_sample)

    def _on_sample(self, sample: Any) -> None:
        try:
            value = getattr(wire.unpack(*wire.sample_parts(sample)), self.spec.field)
        except MessageError:
            return  # the publishing node's runtime reports bad payloads (docs/robustness.md)
        except AttributeError:
            return  # a valid message of another type on that key (a stray publisher): not the status
        self.show(value, time.monotonic())

    def show(self, value: Any, now: float) -> None:
        """Log ``value`` if it differs from the last one shown and ``min_interval_s`` has passed."""
        if value == self.shown or (self.shown_at is not None and now - self.shown_at < self.spec.min_interval_s):
            return
        self.shown, self.shown_at = value, now
        log.info("%s: %s", self.spec.topic, value)

    def close(self) -> None:
        if self._subscriber is not None:
            self._subscriber.undeclare()
            self._subscriber = None
