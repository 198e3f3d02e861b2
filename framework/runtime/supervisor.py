"""What the launcher's helpers may use of it: the narrow interfaces the launcher
(:class:`handflow.framework.runtime.launcher.Launcher`) implements for its parameter service
(:mod:`.param_service`), its file watcher (:mod:`.watch`) and its start-up lines (:mod:`.startup`).
They sit below all of them, so no helper imports the launcher that runs it (docs/architecture.md,
"Layers")."""

from __future__ import annotations

import subprocess
from collections.abc import Callable, Collection, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from ..graphs.model import Graph
    from .zygote import ForkedProcess


class SupervisedUnit(Protocol):
    """A process the launcher supervises, running these nodes."""

    name: str
    node_ids: list[str]
    proc: Any  # its process while it runs, else None


class Supervisor(Protocol):
    """The graph, its process units and the supervising thread: what both helpers use."""

    graph: Graph

    @property
    def units(self) -> Sequence[SupervisedUnit]: ...

    @property
    def state_dir(self) -> Path: ...

    def call_soon(self, call: Callable[[], object]) -> None:
        """Run ``call()`` in the supervising thread (from any other thread)."""

    def ready(self, unit: Any) -> bool:
        """The unit runs and each of its nodes has reported since its start."""


class ParamHost(Supervisor, Protocol):
    """What :class:`.param_service.ParamService` needs: the hub session, and restarting a unit."""

    session: Any  # the hub's Zenoh session

    def restart(self, unit: Any, why: str) -> None:
        """Stop the unit in order and start it again (in the supervising thread)."""


class WatchHost(Supervisor, Protocol):
    """What :class:`.watch.Watcher` needs (``handflow run --watch``): reloading an edit, checking it in a process."""

    host: str | None
    edited: set[Path]  # plugin source files edited during the run

    def reload(self, graph: Graph, text: str, touched: set[str], why: str) -> list[str]:
        """Run ``graph``, an edit of the running one; one line per unit started or stopped."""

    def start_process(
        self, module: str, args: list[str], what: str, edited: Collection[Path] = ()
    ) -> subprocess.Popen | ForkedProcess:
        """A process running ``module.main(args)`` (forked from the zygote when it can)."""


class StartupHost(Protocol):
    """What :class:`.startup.StartupProgress` reads: the units and the nodes that reported (their last status)."""

    health: Mapping[str, Any]

    @property
    def units(self) -> Sequence[SupervisedUnit]: ...
