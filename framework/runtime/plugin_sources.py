"""The source files a plugin is made of, and forgetting them in a process that must run their new
version (``handflow run --watch``, docs/tuning.md "Editing a running graph").

A plugin's files are the module that defines its node class and the modules of that module's
package (its folder and sub-folders) it imports, directly or through each other, as the names they
bind tell (a module, class or function imported from one counts, a bare constant does not), with
the ``__init__.py`` of the packages in between.  A
plugin that is a top-level module is that file alone.  Code it imports from elsewhere (another
package, the framework) is not watched.
"""

from __future__ import annotations

import importlib
import importlib.util
import logging
import sys
from collections.abc import Collection
from pathlib import Path
from types import ModuleType

log = logging.getLogger("handflow.watch")


def _file(module: ModuleType | None) -> Path | None:
    path = getattr(module, "__file__", None)
    return Path(path).resolve() if path and path.endswith(".py") else None


def _module_of(value: object) -> ModuleType | None:
    if isinstance(value, ModuleType):
        return value
    try:
        name = getattr(value, "__module__", None)
    except Exception:  # an object whose attribute lookup fails is no import
        return None
    return sys.modules.get(name) if isinstance(name, str) else None


def plugin_files(cls: type) -> frozenset[Path]:
    """The source files of the plugin whose node class is ``cls`` (see the module docstring)."""
    module = sys.modules[cls.__module__]
    first = _file(module)
    if first is None:
        return frozenset()
    package = first.parent if "." in module.__name__ else None
    files: set[Path] = set()
    todo = [module]
    while todo:
        module = todo.pop()
        path = _file(module)
        if path is None or path in files:
            continue
        files.add(path)
        if package is None:
            continue
        parents = [sys.modules.get(module.__name__.rpartition(".")[0])]  # its package's __init__ re-exports it
        for dep in [*parents, *map(_module_of, list(vars(module).values()))]:
            dep_path = _file(dep)
            if dep_path is not None and dep_path not in files and dep_path.is_relative_to(package):
                todo.append(dep)
    return frozenset(files)


def forget(files: Collection[str | Path]) -> None:
    """Drop the modules imported from ``files`` so that the next import runs their current source."""
    paths = {Path(f).resolve() for f in files}
    if not paths:
        return
    for name, module in list(sys.modules.items()):
        if _file(module) in paths:
            del sys.modules[name]
    importlib.invalidate_caches()


def drop_bytecode(path: Path) -> None:
    """Remove the cached bytecode of ``path``: an edit within the second of the last one that kept the
    file's size would otherwise import the cached, older code (the cache is checked by mtime in seconds)."""
    if sys.implementation.cache_tag is None:  # an interpreter that writes no bytecode cache
        return
    cached = Path(importlib.util.cache_from_source(str(path)))
    try:
        cached.unlink(missing_ok=True)
    except OSError as exc:
        log.warning(
            "could not remove %s (%s): an edit within a second of the last may load the older code", cached, exc
        )
