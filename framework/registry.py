"""Plugin and command discovery through entry points (docs/architecture.md).

Built-in plugins register exactly like third-party ones: entry-point group ``handflow.plugins``
(name → ``module:NodeClass``).  A plugin that was renamed keeps its old entry point; its class
names the current one in ``plugin_name`` and loading it by the old name warns (docs/pipelines.md).  CLI commands come from group ``handflow.commands``.
"""

from __future__ import annotations

import difflib
import sys
import sysconfig
import traceback
import warnings
from dataclasses import dataclass
from functools import cache
from importlib.metadata import EntryPoint, entry_points
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the node base class (numpy, pydantic) loads with the first plugin, not with `--help`
    from .plugin import Node

PLUGIN_GROUP = "handflow.plugins"
COMMAND_GROUP = "handflow.commands"


class PluginError(LookupError):
    """An unknown plugin, or one whose module fails to import."""


@dataclass(frozen=True)
class PluginEntry:
    name: str
    target: str
    entry_point: EntryPoint

    def load(self) -> type[Node]:
        from .plugin import Node

        try:
            cls = self.entry_point.load()
        except Exception as exc:  # an import error inside a plugin must not hide the others
            at = failing_line(exc)
            raise PluginError(
                f"plugin '{self.name}' ({self.target}) failed to load: {type(exc).__name__}: {exc}"
                + (f" (at {at})" if at else "")
            ) from exc
        if not (isinstance(cls, type) and issubclass(cls, Node)):
            raise PluginError(f"plugin '{self.name}' ({self.target}) is not a handflow.framework.plugin.Node subclass")
        return cls


def failing_line(exc: BaseException) -> str | None:
    """``file:line`` of the code that made a plugin's import fail: the line of a syntax error, else the
    deepest frame of the traceback in code not installed (the plugin being written), else the first
    frame outside the standard library (the installed plugin's module); None for a module not found."""
    if isinstance(exc, SyntaxError) and exc.filename:
        return f"{exc.filename}:{exc.lineno}"
    stdlib = sysconfig.get_paths()["stdlib"]
    frames = [
        f
        for f in traceback.extract_tb(exc.__traceback__)
        if not f.filename.startswith(("<", stdlib)) and f.filename != __file__
    ]
    own = [f for f in frames if not f.filename.startswith(sys.prefix)]
    at = own[-1] if own else frames[0] if frames else None
    return f"{at.filename}:{at.lineno}" if at else None


@cache
def plugin_entries() -> dict[str, PluginEntry]:
    """All installed plugins by name (not yet imported)."""
    return {ep.name: PluginEntry(ep.name, ep.value, ep) for ep in entry_points(group=PLUGIN_GROUP)}


def unknown_plugin(name: str) -> str:
    """What to say about a plugin name that is not installed: the closest names, then all of them."""
    names = sorted(plugin_entries())
    close = difflib.get_close_matches(name, names, n=3, cutoff=0.6)
    guess = f"did you mean {' or '.join(repr(c) for c in close)}? " if close else ""
    return f"unknown plugin '{name}'; {guess}installed plugins: {', '.join(names)}"


def load_plugin(name: str) -> type[Node]:
    """The node class of plugin ``name``; :class:`PluginError` lists the known names if unknown."""
    entries = plugin_entries()
    if name not in entries:
        raise PluginError(unknown_plugin(name))
    cls = entries[name].load()
    canonical = getattr(cls, "plugin_name", None)
    if canonical and canonical != name:
        warnings.warn(
            f"plugin '{name}' is now called '{canonical}'; the old name still works but will be "
            f"removed: write 'plugin: {canonical}' in the graph",
            FutureWarning,
            stacklevel=2,
        )
    return cls


def command_entries() -> list[EntryPoint]:
    """CLI command registrations, sorted by (dotted) name."""
    return sorted(entry_points(group=COMMAND_GROUP), key=lambda ep: ep.name)
