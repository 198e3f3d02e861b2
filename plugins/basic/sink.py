"""Sink that counts, logs, or writes what it receives (any message type)."""

from __future__ import annotations

import json
import time

from pydantic import Field

from handflow.framework.files.params import StrictModel
from handflow.framework.messages import Message
from handflow.framework.plugin import Node


class SinkParams(StrictModel):
    log_every: int = Field(0, ge=0, description="log every n-th message (0: only a summary at teardown)")
    jsonl: str | None = Field(
        None,
        description="write one JSON line per message (arrival ns, latency ns, message); every run replaces the "
        "file, a node restarted within the run continues it",
    )


class Sink(Node):
    """Counts messages on input 'in', optionally logs them or writes them as JSON lines."""

    Params = SinkParams
    inputs = {"in": Message}

    def setup(self) -> None:
        self.count = 0
        # a new run never appends to an old run's lines (docs/recording.md, "Replaying")
        mode = "a" if self.ctx.restarted else "w"
        self.file = open(self.ctx.output_path(self.params.jsonl), mode, buffering=1) if self.params.jsonl else None

    def on_message(self, port: str, msg: Message) -> None:
        self.count += 1
        if self.file is not None:
            arrival = time.time_ns()
            line = {"arrival_ns": arrival, "latency_ns": arrival - msg.header.stamp_ns, "msg": msg.to_dict()}
            self.file.write(json.dumps(line) + "\n")
        if self.params.log_every and self.count % self.params.log_every == 0:
            self.ctx.log.info("#%d from %s seq %d: %s", self.count, msg.header.source, msg.header.seq, msg)

    def teardown(self) -> None:
        self.ctx.log.info("received %d message(s)", self.count)
        if self.file is not None:
            self.file.close()
