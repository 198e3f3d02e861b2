"""The plugin base class every node derives from (docs/architecture.md).

A plugin declares typed input and output ports, a pydantic ``Params`` model, and any of the hooks
``setup`` / ``on_message`` / ``tick`` / ``teardown`` (and ``on_params`` for parameters it takes while
running, docs/tuning.md).  The runtime never runs two hooks of a node
(or of nodes sharing a process) at the same time, so a node never needs locks.  Everything the node may do to the outside world goes through its
:class:`Context`: publish on an output port, read the clock (virtual during lock-step replay), log,
resolve a path relative to the graph file.

Example::

    class Gain(Node):
        class Params(StrictModel):
            gain: float = 1.0
        inputs = {"in": Array}
        outputs = {"out": Array}

        def on_message(self, port, msg):
            self.ctx.publish("out", Array(data=msg.data * self.params.gain))
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any, ClassVar, Protocol

from pydantic import BaseModel

from .files.params import StrictModel
from .messages import Message


class NoParams(StrictModel):
    """Params model of a plugin without parameters (unknown keys are rejected)."""


class Context(Protocol):
    """What the runtime gives a node (see ``handflow.framework.runtime.runner.NodeContext`` for the implementation)."""

    node_id: str
    graph_name: str
    log: logging.Logger
    restarted: bool
    """True when the node was restarted after a failure within the same run: an output file opened in
    ``setup`` continues (append) instead of starting afresh (docs/reliability.md)."""

    def publish(self, port: str, msg: Message, stamp_ns: int | None = None) -> None:
        """Validate ``msg`` and publish it on output ``port``; header filled in (stamp defaults to now)."""

    def allocate(self, port: str, nbytes: int) -> Any:
        """A writable ``uint8`` array of ``nbytes`` to fill in place and publish on ``port`` as an image's
        ``data`` (saves the copy of ``Image.from_array``); docs/shared_memory.md."""

    def now_ns(self) -> int:
        """Current time in ns: wall clock live, virtual time of the replayed stream in lock-step."""

    def resolve_path(self, path: str | Path) -> Path:
        """An input path from the params (model, calibration), made absolute relative to the graph file's folder."""

    def output_path(self, path: str | Path) -> Path:
        """An output path from the params (log, recording), made absolute relative to the current directory;
        its folder is created."""


class Node:
    """Base class of all plugins.

    Class attributes to set in a subclass:
    - ``Params``: the ``params:`` block, a :class:`~handflow.framework.files.params.StrictModel` subclass
      (unknown keys rejected; choices as ``Literal``);
    - ``inputs`` / ``outputs``: port name → message type;
    - ``description``: one line shown by ``handflow plugins`` (defaults to the docstring's first line);
    - ``requires``: modules beyond the core → the extra that installs them, e.g. ``{"mne_lsl": "lsl"}``
      (checked by ``handflow validate``; files and devices the params name are declared with
      :class:`~handflow.framework.files.inputs.InputPath`, docs/pipelines.md).
    A node with a ``tick`` override is ticked at ``tick_rate_hz()`` (default: ``params.rate_hz``).
    """

    Params: ClassVar[type[BaseModel]] = NoParams
    inputs: ClassVar[dict[str, type[Message]]] = {}
    outputs: ClassVar[dict[str, type[Message]]] = {}
    description: ClassVar[str] = ""
    requires: ClassVar[dict[str, str]] = {}

    def __init__(self, params: BaseModel, ctx: Context) -> None:
        self.params = params
        self.ctx = ctx

    # -- hooks ------------------------------------------------------------------------------
    def setup(self) -> None:
        """Acquire resources (open devices, load models). Called once before any message or tick."""

    def on_message(self, port: str, msg: Message) -> None:
        """Handle one message arriving on input ``port``."""

    def tick(self) -> None:
        """Periodic work at ``tick_rate_hz()``."""

    def teardown(self) -> None:
        """Release resources; also called on Ctrl-C / SIGTERM and at the end of ``--duration``."""

    def on_params(self, params: BaseModel, changed: frozenset[str]) -> None:
        """Take new ``params`` while running: the ``changed`` keys are parameters marked
        :func:`~handflow.framework.files.params.live`, already validated by ``Params``.  Default: use them
        from now on (``self.params = params``); override to rebuild what was derived from them, calling
        ``super().on_params(...)``.  Raising ``ValueError`` refuses the change (the old params stay);
        docs/tuning.md."""
        self.params = params

    def safe_output(self) -> dict[str, Message]:
        """Messages to publish when the node stops or its inputs go stale (port → message). Default: none."""
        return {}

    # -- scheduling -------------------------------------------------------------------------
    @classmethod
    def has_tick(cls) -> bool:
        return cls.tick is not Node.tick

    def tick_rate_hz(self) -> float | None:
        if not self.has_tick():
            return None
        rate = getattr(self.params, "rate_hz", None)
        if rate is None:
            raise TypeError(
                f"{type(self).__name__} overrides tick() but its Params has no 'rate_hz'; override tick_rate_hz()"
            )
        return float(rate)

    @classmethod
    def input_types(cls, params: BaseModel) -> dict[str, type[Message]]:
        """Input port types for these params; ``inputs`` unless a plugin's types depend on its params."""
        return cls.inputs

    @classmethod
    def output_types(cls, params: BaseModel) -> dict[str, type[Message]]:
        """Output port types for these params; ``outputs`` unless a plugin's types depend on its params."""
        return cls.outputs

    @classmethod
    def summary(cls) -> str:
        doc = cls.description or (cls.__doc__ or "").strip().splitlines()[0:1]
        return doc if isinstance(doc, str) else (doc[0] if doc else "")

    @classmethod
    def params_schema(cls) -> dict[str, Any]:
        return cls.Params.model_json_schema()
