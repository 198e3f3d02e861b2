"""Recorded parameter changes, applied again by a lock-step replay (docs/tuning.md, docs/recording.md).

A recording of a graph holds every parameter change accepted while it ran (``ParamChange`` on
``handflow/<graph>/_params/changes``), stamped with the first input the node handled with the new
value.  :class:`RecordedChanges` hands each change to the node again, through the node's own
parameter service (the same validation and ``on_params`` hook), just before the replay releases
the first message stamped at or after it, so the node handles the same inputs with the same values
as in the live run.  Changes made with ``--restart`` are not applied (a replay does not restart nodes).
"""

from __future__ import annotations

import json
import logging
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .. import keys
from ..files.mcap_reader import iter_recording
from ..messages import ParamChange
from ..runtime.param_service import NODE_TIMEOUT_S
from .replay import ReplayError

log = logging.getLogger("handflow.replay")


class ParamReplayError(ReplayError):
    """A recorded change the replayed node refused or did not answer; the text says which and why."""


@dataclass(frozen=True)
class RecordedChange:
    stamp_ns: int
    node: str
    key: str
    value: Any


def read_changes(path: str | Path, recorded_graph: str) -> tuple[list[RecordedChange], list[ParamChange]]:
    """The live changes of ``recorded_graph`` in ``path`` in stamp order, and the restarts among them."""
    live, restarts = [], []
    for rm in iter_recording(path, [keys.params_key(recorded_graph)]):
        change = rm.decode()
        if not isinstance(change, ParamChange):
            continue
        if change.restart:
            restarts.append(change)
        else:
            live.append(RecordedChange(change.header.stamp_ns, change.node, change.key, json.loads(change.value)))
    return sorted(live, key=lambda c: c.stamp_ns), restarts


class RecordedChanges:
    """Applies recorded changes to a lock-step graph's nodes as the replay's stamps reach them."""

    def __init__(self, session: Any, graph: Any, changes: list[RecordedChange]) -> None:
        self.session, self.graph = session, graph
        missing = sorted({c.node for c in changes} - set(graph.nodes))
        if missing:
            log.warning(
                "the recording changed parameters of node(s) %s, which graph '%s' lacks: not applied",
                ", ".join(missing),
                graph.name,
            )
        self.changes = [c for c in changes if c.node in graph.nodes]
        self.rewind()

    def rewind(self) -> None:
        """All changes pending again, for a replay started over from the first message."""
        self.pending = deque(self.changes)
        self.applied = 0

    def before(self, stamp_ns: int) -> None:
        """Apply every change stamped at or before ``stamp_ns`` (the next message's stamp)."""
        while self.pending and self.pending[0].stamp_ns <= stamp_ns:
            change = self.pending.popleft()
            request = {"op": "set", "key": change.key, "value": change.value}
            answers = [
                json.loads(r.ok.payload.to_bytes())
                for r in self.session.get(
                    keys.node_params_key(self.graph.name, change.node),
                    payload=json.dumps(request),
                    timeout=NODE_TIMEOUT_S,
                )
                if r.ok is not None
            ]
            if not answers or not answers[0].get("ok"):
                why = answers[0].get("error") if answers else "no answer"
                raise ParamReplayError(
                    f"recorded change {change.node}.{change.key} = {change.value!r} not applied: {why}"
                )
            self.applied += 1
