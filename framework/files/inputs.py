"""Preflight: the inputs a node will read, checked before any process starts (docs/pipelines.md, "Inputs").

A plugin declares every file, folder or device its parameters name with :class:`InputPath` in an
``Annotated`` type (``InputFile`` / ``InputDir`` for the plain cases), and the Python modules it
needs beyond the core with ``Node.requires`` (module → extra).  :func:`node_input_problems` walks a
node's validated params (nested models and lists included) and returns one ``(location, message)``
per input that is missing, of the wrong kind or refused by the declaration's ``check`` (a model
file's format and version), so ``handflow validate`` and ``handflow run`` list them all with their
graph lines.  The framework knows no plugin: the declarations carry what to say.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal, get_args, get_origin

from pydantic import BaseModel


@dataclass(frozen=True)
class InputPath:
    """Marks a ``str`` parameter as a path the node reads, relative to the graph file's folder.

    ``kind``: ``file``, ``dir``, ``any`` (either) or ``device`` (must exist; a serial port, say);
    ``what`` names it in messages and ``hint`` says how to get a good one; ``check(path)`` raises
    ``ValueError`` (or ``OSError``) with its own message for an existing but unusable file or folder
    (the plugin's own loader, reading what the node reads at start without building anything);
    values for which ``skip(value)`` is true name no path (e.g. a glove's ``emulator``).
    """

    kind: Literal["file", "dir", "any", "device"] = "file"
    what: str = "input file"
    hint: str = "fix the path (relative to the graph file's folder)"
    check: Callable[[Path], None] | None = None
    skip: Callable[[str], bool] | None = None

    def problem(self, value: str, base_dir: Path) -> str | None:
        """What is wrong with the input ``value`` names, or None."""
        if self.skip is not None and self.skip(value):
            return None
        raw = Path(value).expanduser()
        path = raw if raw.is_absolute() else base_dir / raw
        found = {"file": path.is_file, "dir": path.is_dir, "any": path.exists, "device": path.exists}[self.kind]()
        if not found:
            kind = {"file": "file", "dir": "folder", "any": "file or folder", "device": "device"}[self.kind]
            where = "" if raw.is_absolute() else f" (looked for {path})"
            exists = " exists but" if path.exists() else ""
            return f"{self.what} {value}:{exists} no such {kind}{where}; {self.hint}"
        if self.check is not None and (path.is_file() or path.is_dir()):  # not a device: it is opened at start
            try:
                self.check(path)
            except (ValueError, OSError) as exc:
                return str(exc)
        return None


InputFile = Annotated[str, InputPath()]
"""A parameter naming a file the node reads."""
InputDir = Annotated[str, InputPath("dir", "input folder")]
"""A parameter naming a folder the node reads."""


def _markers(annotation: Any) -> list[InputPath]:
    """The :class:`InputPath` declarations inside a type (``Annotated``, ``| None``, ``list[...]``)."""
    found = []
    if get_origin(annotation) is Annotated:
        found += [m for m in annotation.__metadata__ if isinstance(m, InputPath)]
    for arg in get_args(annotation):
        if arg is not None and not isinstance(arg, InputPath):
            found += _markers(arg)
    return found


def _model_of(annotation: Any) -> type[BaseModel] | None:
    """The params model a field's type names (``Model``, ``Model | None``), for values not yet validated."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    return next(filter(None, map(_model_of, get_args(annotation))), None)


def declared_inputs(
    model: type[BaseModel], values: BaseModel | dict, loc: tuple = ()
) -> Iterator[tuple[tuple, str, InputPath]]:
    """Every (location in params, value, declaration) of the inputs named by ``values``: the validated
    params of ``model``, or its raw dict (params that failed validation: the keys that passed, so one
    mistake does not hide a missing file; docs/pipelines.md)."""
    for name, info in model.model_fields.items():
        if isinstance(values, BaseModel):
            value = getattr(values, name)
        elif name in values:
            value = values[name]
        elif info.is_required():
            continue
        else:
            value = info.get_default(call_default_factory=True)
        markers = [m for m in info.metadata if isinstance(m, InputPath)] + _markers(info.annotation)
        if isinstance(value, BaseModel):
            yield from declared_inputs(type(value), value, loc + (name,))
        elif isinstance(value, dict) and (sub := _model_of(info.annotation)) is not None:
            yield from declared_inputs(sub, value, loc + (name,))
        elif markers and isinstance(value, str):
            yield loc + (name,), value, markers[0]
        elif markers and isinstance(value, list):
            for i, item in enumerate(value):
                if isinstance(item, str):
                    yield loc + (name, i), item, markers[0]


def missing_modules(requires: dict[str, str]) -> list[str]:
    """Messages for the modules of ``requires`` (module → extra) that are not installed."""
    missing: dict[str, list[str]] = {}
    for module, extra in requires.items():
        try:
            found = importlib.util.find_spec(module) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            missing.setdefault(extra, []).append(module)
    return [
        f"needs {', '.join(mods)}, which is not installed: install it with pip install 'handflow[{extra}]'"
        for extra, mods in missing.items()
    ]


def node_input_problems(cls: Any, params: BaseModel | dict, base_dir: Path) -> list[tuple[tuple, str]]:
    """(location in the node's params, or () for the node itself; message) per unusable input;
    ``params`` validated, or the raw ones that passed (see :func:`declared_inputs`)."""
    problems: list[tuple[tuple, str]] = [((), msg) for msg in missing_modules(getattr(cls, "requires", {}))]
    for loc, value, marker in declared_inputs(cls.Params, params):
        if (msg := marker.problem(value, base_dir)) is not None:
            problems.append((loc, msg))
    return problems
