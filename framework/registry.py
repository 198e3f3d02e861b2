"""Plugin and command discovery through entry points (docs/architecture.md).

Built-in plugins register exactly like third-party ones: entry-point group ``handflow.plugins``
(name → ``module:NodeClass``).  A plugin that was renamed keeps its old entry point; its class
names the current one in ``plugin_name`` and loading it by the old name warns (docs/pipelines.md).  A graph
may also name a plugin by its source file, ``./my_plugin.py:MyNode`` (:func:`load_file_plugin`; docs/pipelines.md,
"A plugin given by path").  CLI commands come from group ``handflow.commands``.
"""

from __future__ import annotations

import difflib
import hashlib
import importlib.util
import inspect
import re
import sys
import sysconfig
import traceback
import warnings
from dataclasses import dataclass
from functools import cache
from importlib.metadata import EntryPoint, entry_points
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the node base class (numpy, pydantic) loads with the first plugin, not with `--help`
    from .plugin import Node

PLUGIN_GROUP = "handflow.plugins"
COMMAND_GROUP = "handflow.commands"
PATH_PREFIXES = ("./", "../", "/")  # a plugin named so is a source file (docs/pipelines.md)


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


def is_path_plugin(name: str) -> bool:
    """Whether a graph names this plugin by its source file (``./my_plugin.py:MyNode``)."""
    return name.startswith(PATH_PREFIXES)


def load_file_plugin(name: str, base_dir: Path) -> type[Node]:
    """The node class of ``FILE.py:Class`` (FILE relative to ``base_dir``, the graph file's folder, unless
    absolute).  The module is imported once per process under a name made from its resolved path, so that
    ``--watch`` sees and forgets it like an installed one (:mod:`.runtime.plugin_sources`: the file alone)."""
    from .plugin import Node

    file, _, class_name = name.rpartition(":")
    if not file.endswith(".py") or not class_name.isidentifier():
        raise PluginError(
            f"plugin '{name}': a plugin given by path is written FILE.py:ClassName (e.g. ./my_plugin.py:MyNode), "
            "FILE relative to the graph file's folder"
        )
    try:
        path = (base_dir / file).resolve()
        found = path.is_file()
    except (OSError, ValueError) as exc:  # a name the file system refuses (too long, a NUL byte)
        raise PluginError(f"plugin '{name}': {file!r} is not a usable path: {exc}") from None
    if not found:
        raise PluginError(
            f"plugin '{name}': no file {path} (a path is relative to the graph file's folder, {base_dir})"
        )
    stem, digest = re.sub(r"\W", "_", path.stem), hashlib.sha1(str(path).encode()).hexdigest()[:10]
    module_name = f"handflow_plugin_{stem}_{digest}"
    module = sys.modules.get(module_name)
    if module is None:
        spec = importlib.util.spec_from_file_location(module_name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[module_name] = module
        try:
            spec.loader.exec_module(module)
        except Exception as exc:  # its own error, where it happened
            del sys.modules[module_name]
            at = failing_line(exc)
            raise PluginError(
                f"plugin '{name}' failed to load: {type(exc).__name__}: {exc}" + (f" (at {at})" if at else "")
            ) from exc
    cls = getattr(module, class_name, None)
    if cls is None:
        nodes = [k for k, v in vars(module).items() if isinstance(v, type) and issubclass(v, Node) and v is not Node]
        raise PluginError(
            f"plugin '{name}': {path}:1 defines no '{class_name}' "
            f"(its Node classes: {', '.join(nodes) or 'none'}); check the name after ':'"
        )
    if not (isinstance(cls, type) and issubclass(cls, Node)):
        try:
            where = f"{path}:{inspect.getsourcelines(cls)[1]}"
        except (OSError, TypeError):
            where = str(path)
        raise PluginError(
            f"plugin '{name}': '{class_name}' (at {where}) is not a handflow.framework.plugin.Node subclass"
        )
    return cls


def load_plugin(name: str, base_dir: Path | None = None) -> type[Node]:
    """The node class of plugin ``name`` (installed, or a file relative to ``base_dir``: :func:`load_file_plugin`);
    :class:`PluginError` lists the known names if unknown."""
    if is_path_plugin(name):
        return load_file_plugin(name, base_dir if base_dir is not None else Path.cwd())
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
