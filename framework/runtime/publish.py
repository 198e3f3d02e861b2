"""The publish contract of a node's context (:class:`handflow.framework.plugin.Context`): what the runtime
checks of every message a node publishes, and how it hands out an output buffer.  The runner applies
it to running nodes and :mod:`handflow.framework.testkit.harness` to nodes under test, so a plugin
meets the same checks in both (docs/robustness.md)."""

from __future__ import annotations

import numpy as np

from ..messages import Message, MessageError


def check_publish(
    node_id: str, outputs: dict[str, type[Message]], port: str, msg: Message, validated: bool = False
) -> None:
    """The publisher-side checks shared by the runtime and the harness; ``validated`` skips the
    message's own check (a received message forwarded unchanged was checked when it was decoded)."""
    expected = outputs.get(port)
    if expected is None:
        raise MessageError(f"node '{node_id}' has no output port '{port}' (it has: {', '.join(outputs) or 'none'})")
    if not isinstance(msg, expected):
        raise MessageError(f"node '{node_id}' port '{port}' carries {expected.TYPE}, not {type(msg).__name__}")
    if validated:
        return
    try:
        msg.check()
    except MessageError as exc:
        raise MessageError(f"node '{node_id}' port '{port}': {exc}") from None


def allocate_output(node_id: str, outputs: dict[str, type[Message]], port: str, nbytes: int) -> np.ndarray:
    """:meth:`handflow.framework.plugin.Context.allocate`, shared by the runtime and the harness."""
    if port not in outputs:
        raise MessageError(f"node '{node_id}' has no output port '{port}' (it has: {', '.join(outputs) or 'none'})")
    return np.empty(int(nbytes), dtype=np.uint8)
