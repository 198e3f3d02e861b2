"""``--set NODE.KEY=VALUE``: a node parameter given on the command line (docs/pipelines.md, "Parameters from the command line").

The value is YAML (``3``, ``true``, ``[a, b]``, a plain string).  A parameter that names an input
file or folder (declared with :class:`~..files.inputs.InputPath`) is resolved against the current
directory, not the graph file's folder: ``handflow run recognise_gestures --set
segmenter.models=models`` uses ``./models`` whichever folder holds the shipped graph.  The nodes
run the graph file with the values set (the launcher hands them that version of the file).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from ..files.inputs import declared_inputs
from .model import Graph, graph_path, load_graph


class OverrideError(ValueError):
    """A ``--set`` that cannot be applied, with what to change."""


def parse_set(item: str) -> tuple[str, list[str], Any]:
    """``NODE.KEY[.SUBKEY]=VALUE`` → (node id, key path, YAML value)."""
    target, eq, raw = item.partition("=")
    node, _, key = target.strip().partition(".")
    if not eq or not node or not key:
        raise OverrideError(f"--set {item!r}: write NODE.KEY=VALUE, e.g. segmenter.models=models")
    try:
        value = yaml.safe_load(raw) if raw.strip() else ""
    except yaml.YAMLError as exc:
        raise OverrideError(f"--set {item!r}: the value is not YAML ({str(exc).splitlines()[0]})") from None
    return node, key.split("."), value


def _apply(data: dict, sets: Sequence[tuple[str, list[str], Any]]) -> dict:
    nodes = {n.get("id"): n for n in data.get("nodes") or [] if isinstance(n, dict)}
    for node, keys, value in sets:
        if node not in nodes:
            raise OverrideError(
                f"--set {node}.{'.'.join(keys)}: the graph has no node '{node}'; it has {', '.join(map(str, nodes))}"
            )
        params = nodes[node].setdefault("params", {}) or {}
        nodes[node]["params"] = params
        for k in keys[:-1]:
            params = params.setdefault(k, {})
            if not isinstance(params, dict):
                raise OverrideError(f"--set {node}.{'.'.join(keys)}: '{k}' is not a mapping of parameters")
        params[keys[-1]] = value
    return data


def _absolute(value: Any, loc: tuple, inputs: set[tuple]) -> Any:
    """``value`` with the relative paths at the input locations ``inputs`` made absolute against the current directory."""
    if loc in inputs and isinstance(value, str) and not Path(value).expanduser().is_absolute():
        return str(Path.cwd() / value)
    if isinstance(value, list):
        return [_absolute(x, loc + (i,), inputs) for i, x in enumerate(value)]
    return value


def _cwd_paths(graph: Graph, sets: Sequence[tuple[str, list[str], Any]]) -> list[tuple[str, list[str], Any]]:
    """The values of ``sets`` with the relative input paths they name made absolute against the current directory."""
    out = []
    for node, keys, value in sets:
        rn = graph.nodes.get(node)
        inputs = {loc for loc, _, _ in declared_inputs(rn.cls.Params, rn.params)} if rn is not None else set()
        out.append((node, keys, _absolute(value, tuple(keys), inputs)))
    return out


def graph_text_with(argument: str | Path, items: Sequence[str], host: str | None = None) -> str:
    """The graph file's text with the ``--set`` ``items`` applied and their input paths resolved against
    the current directory (module docstring); :class:`OverrideError` or the graph's own errors."""
    sets = [parse_set(i) for i in items]
    path = graph_path(argument)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError):
        load_graph(argument, host=host)  # says what is wrong with the file
        raise
    if not isinstance(data, dict):
        load_graph(argument, host=host)
    text = yaml.safe_dump(_apply(data, sets), sort_keys=False)
    graph = load_graph(argument, host=host, text=text)
    return yaml.safe_dump(_apply(data, _cwd_paths(graph, sets)), sort_keys=False)
