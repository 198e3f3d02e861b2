"""What a graph's launcher says while it starts (docs/pipelines.md, "Start-up"): a first line at once,
a line per node as it becomes ready, and the ready line with the time since the command.

A graph with heavy nodes (models to load, physics to set up) takes seconds to start, more on a busy
machine; these lines say what is going on meanwhile.
"""

from __future__ import annotations

import logging
import time
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .supervisor import StartupHost

log = logging.getLogger("handflow.launcher")


class StartupProgress:
    """The start-up lines of one run; ``t0``: when the command started (``time.monotonic()``)."""

    def __init__(self, t0: float | None = None) -> None:
        self.t0 = time.monotonic() if t0 is None else t0
        self._ready: set[str] = set()  # the nodes that reported ready

    def elapsed(self) -> float:
        return time.monotonic() - self.t0

    def say(self, what: str, *args: object) -> None:
        log.info(what, *args)

    def poll(self, launcher: StartupHost) -> None:
        """A line for each node that reported ready since the last call (once each)."""
        total = sum(len(unit.node_ids) for unit in launcher.units)
        for unit in launcher.units:
            for nid in unit.node_ids:
                if nid not in self._ready and unit.proc is not None and nid in launcher.health:
                    self._ready.add(nid)
                    shared = f" (process {unit.name})" if unit.node_ids != [unit.name] else ""
                    log.info("ready: %s%s, %d/%d, %.1fs", nid, shared, len(self._ready), total, self.elapsed())

    def all_ready(self, since_start_s: float) -> None:
        log.info("all nodes ready after %.1fs (%.1fs after the command)", since_start_s, self.elapsed())
