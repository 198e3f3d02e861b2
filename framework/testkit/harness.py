"""Drive one node in-process, without Zenoh: for unit tests of a plugin's node wrapper.

The harness builds the node exactly as the runtime does (params validated by the plugin's model,
published messages checked by the runtime's publish contract, :mod:`handflow.framework.runtime.publish`),
but delivers messages and ticks on demand and keeps what the node publishes.  End-to-end behaviour is tested with ``handflow run``.
"""

from __future__ import annotations

import logging
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from ..messages import Header, Message, MessageError
from ..plugin import Node
from ..runtime.publish import allocate_output, check_publish


class HarnessContext:
    """A :class:`handflow.framework.plugin.Context` that records publications and uses a settable clock."""

    def __init__(self, node_id: str, base_dir: Path, outputs: dict[str, type[Message]]) -> None:
        self.node_id = node_id
        self.graph_name = "test"
        self.log = logging.getLogger(f"handflow.node.{node_id}")
        self.base_dir = base_dir
        self.clock_ns = 0
        self.restarted = False
        self.published: dict[str, list[Message]] = defaultdict(list)
        self._outputs = outputs
        self._seq: dict[str, int] = defaultdict(int)

    def publish(self, port: str, msg: Message, stamp_ns: int | None = None) -> None:
        check_publish(self.node_id, self._outputs, port, msg)
        self._seq[port] += 1
        msg.header = Header(self.node_id, self._seq[port], self.clock_ns if stamp_ns is None else stamp_ns)
        self.published[port].append(msg)

    def allocate(self, port: str, nbytes: int) -> np.ndarray:
        return allocate_output(self.node_id, self._outputs, port, nbytes)

    def now_ns(self) -> int:
        return self.clock_ns

    def resolve_path(self, path: str | Path) -> Path:
        p = Path(path).expanduser()
        return p if p.is_absolute() else (self.base_dir / p).resolve()

    def output_path(self, path: str | Path) -> Path:
        p = Path(path).expanduser().resolve()
        p.parent.mkdir(parents=True, exist_ok=True)
        return p


class NodeHarness:
    """``h = NodeHarness(MyNode, {"gain": 2}); h.setup(); h.send("in", msg); h.published["out"]``.

    As in the runtime, a :class:`MessageError` raised while handling a message drops that message:
    ``h.dropped`` lists ``(port, reason)`` (docs/robustness.md).
    """

    def __init__(
        self,
        node_cls: type[Node],
        params: dict[str, Any] | None = None,
        node_id: str = "node",
        base_dir: str | Path = ".",
    ) -> None:
        validated = node_cls.Params.model_validate(params or {})
        self.ctx = HarnessContext(node_id, Path(base_dir).resolve(), node_cls.output_types(validated))
        self.node = node_cls(validated, self.ctx)
        self.dropped: list[tuple[str, str]] = []

    @property
    def published(self) -> dict[str, list[Message]]:
        return self.ctx.published

    def setup(self) -> NodeHarness:
        self.node.setup()
        return self

    def send(self, port: str, msg: Message, stamp_ns: int | None = None) -> None:
        if port not in self.node.inputs:
            raise KeyError(f"no input port '{port}'")
        if stamp_ns is not None:
            self.ctx.clock_ns = stamp_ns
        msg.header.stamp_ns = self.ctx.clock_ns
        try:
            self.node.on_message(port, msg)
        except MessageError as exc:
            self.dropped.append((port, str(exc)))
            self.ctx.log.warning("dropped a payload on input '%s': %s", port, exc)

    def set_param(self, key: str, value: Any) -> None:
        """Change a live parameter as ``handflow param set`` does: validated by the node's model, then
        :meth:`Node.on_params`; ``ParamRefused`` (the old params kept) otherwise (docs/tuning.md)."""
        from ..runtime.live_params import take

        take(self.node, self.ctx.node_id, type(self.node).__name__, key, value)

    def tick(self, n: int = 1, advance_ns: int | None = None) -> None:
        rate = self.node.tick_rate_hz()
        step = advance_ns if advance_ns is not None else int(1e9 / rate) if rate else 0
        for _ in range(n):
            self.ctx.clock_ns += step
            self.node.tick()

    def teardown(self) -> None:
        self.node.teardown()
