"""One YAML loader for every file a user writes — graphs, training configs, calibrations, glove
profiles: syntax errors and validation problems come back as ``file:line: what to change``
(docs/robustness.md)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

M = TypeVar("M", bound=BaseModel)


@dataclass
class Problem:
    line: int
    message: str


class YamlFileError(ValueError):
    """A file with problems; ``str()`` lists them as ``file:line: message``."""

    def __init__(self, path: Path | str, problems: list[Problem]) -> None:
        self.path, self.problems = Path(path), problems
        super().__init__("\n".join(f"{path}:{p.line}: {p.message}" for p in problems))


def line_index(node: yaml.Node, path: tuple = (), out: dict | None = None) -> dict[tuple, int]:
    """Map every key path of a composed YAML document to its 1-based line."""
    out = {} if out is None else out
    out.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            out[path + (k.value,)] = k.start_mark.line + 1
            line_index(v, path + (k.value,), out)
    elif isinstance(node, yaml.SequenceNode):
        for i, v in enumerate(node.value):
            line_index(v, path + (i,), out)
    return out


def line_of(lines: dict[tuple, int], loc: tuple) -> int:
    """The line of ``loc``, or of its nearest enclosing key."""
    loc = tuple(loc)
    while loc and loc not in lines:
        loc = loc[:-1]
    return lines.get(loc, 1)


def pydantic_problems(
    exc: ValidationError, lines: dict[tuple, int], prefix: tuple = (), what: str = ""
) -> list[Problem]:
    """One :class:`Problem` per validation error, at the line of the offending key."""
    problems = []
    for err in exc.errors():
        loc = prefix + tuple(err["loc"])
        name = ".".join(str(p) for p in err["loc"]) or "(top level)"
        hint = err["msg"]
        if err["type"] == "extra_forbidden":
            hint = "unknown field; remove it or check its spelling"
        elif err["type"] == "missing":
            hint = "required field is missing; add it"
        problems.append(Problem(line_of(lines, loc), f"{what}{name}: {hint}"))
    return problems


def parse(text: str) -> tuple[Any, dict[tuple, int]] | Problem:
    """The YAML data and its line index, or the :class:`Problem` of a syntax error."""
    try:
        doc = yaml.compose(text)
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark else 1
        return Problem(line, f"YAML syntax error: {getattr(exc, 'problem', exc)}; fix the indentation/quoting there")
    return data, (line_index(doc) if doc is not None else {})


def load_model(path: str | Path, model: type[M] | None = None, choose=None) -> M:
    """Read a YAML file into a pydantic ``model`` (or the model ``choose(data)`` returns for the
    file's data); every problem raises :class:`YamlFileError` with its line."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise YamlFileError(p, [Problem(1, f"cannot read the file: {exc}")]) from None
    parsed = parse(text)
    if isinstance(parsed, Problem):
        raise YamlFileError(p, [parsed])
    data, lines = parsed
    if not isinstance(data, dict):
        raise YamlFileError(p, [Problem(1, f"the file must hold a mapping of fields, got {type(data).__name__}")])
    cls = choose(data) if choose is not None else model
    try:
        return cls.model_validate(data)
    except ValidationError as exc:
        raise YamlFileError(p, pydantic_problems(exc, lines)) from None
