"""``handflow param dump [FILE]`` and ``handflow param load FILE [--restart]``: a running graph's parameters
as a YAML file ``NODE: {KEY: VALUE}``, written and applied again (docs/tuning.md, "Parameter files").

Load sends only the keys whose value in the file differs from the node's current one: live keys one
by one (each takes effect at once), the start-only keys of a node together with ``--restart`` (one
restart per node), else each is refused by its node with the reason.  Every name is checked before
anything is sent: an unknown node or key changes nothing.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from ..files.yaml import line_of, parse

Ask = Callable[[str, dict[str, Any], float], list[dict[str, Any]]]
"""Sends one request to a node (``*``: every node) with a timeout; the replies."""


class ParamFileError(ValueError):
    """A parameter file that cannot be read or is not ``NODE: {KEY: VALUE}``; the text says where and why."""


def read_param_file(text: str, name: str = "FILE") -> dict[str, dict[str, Any]]:
    """The ``{node: {key: value}}`` of a parameter file's text; :class:`ParamFileError` as ``name:line: ...``."""
    try:
        parsed = parse(text)
    except (yaml.YAMLError, TypeError, ValueError, RecursionError) as exc:  # e.g. a mapping used as a key
        raise ParamFileError(f"{name}:1: not a parameter file: {type(exc).__name__}: {exc}") from None
    if not isinstance(parsed, tuple):
        raise ParamFileError(f"{name}:{parsed.line}: {parsed.message}")
    data, lines = parsed
    if not isinstance(data, dict) or not data:
        raise ParamFileError(
            f"{name}:1: a parameter file maps node ids to their parameters, e.g. 'scale: {{gain: 2.0}}' "
            "(as `handflow param dump` writes it)"
        )
    out: dict[str, dict[str, Any]] = {}
    for node, params in data.items():
        where = f"{name}:{line_of(lines, (node,))}"
        if not isinstance(node, str) or not node:
            raise ParamFileError(f"{where}: node id {node!r} is not a name; write the node's id as in the graph")
        if not isinstance(params, dict):
            raise ParamFileError(f"{where}: node '{node}' needs a mapping of its parameters, e.g. '{node}: {{KEY: 1}}'")
        for key, value in params.items():
            at = f"{name}:{line_of(lines, (node, key))}"
            if not isinstance(key, str) or not key:
                raise ParamFileError(f"{at}: parameter name {key!r} of node '{node}' is not a name")
            if not _is_json(value):
                raise ParamFileError(
                    f"{at}: {node}.{key}: {value!r} is not a plain value (number, text, true/false, null, list or "
                    "mapping of them); quote it if it is text"
                )
        out[node] = dict(params)
    return out


def _is_json(value: Any) -> bool:
    """Whether ``value`` is what a parameter request carries (YAML dates, binary, NaN are not)."""
    if value is None or isinstance(value, (bool, int, str)):
        return True
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, list):
        return all(_is_json(v) for v in value)
    if isinstance(value, dict):
        return all(isinstance(k, str) and _is_json(v) for k, v in value.items())
    return False


def same_value(a: Any, b: Any) -> bool:
    """Equal as parameter values: ``2`` and ``2.0`` are, ``true`` and ``1`` are not."""
    if isinstance(a, bool) or isinstance(b, bool):
        return type(a) is type(b) and a == b
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return a == b
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same_value(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_value(a[k], b[k]) for k in a)
    return type(a) is type(b) and a == b


def dump_text(graph: str, replies: list[dict[str, Any]]) -> str:
    """The parameter file of a graph: every node's current parameters, nodes and keys in order."""
    nodes = {r["node"]: r["params"] for r in sorted(replies, key=lambda r: r["node"])}
    head = f"# parameters of graph '{graph}' (`handflow param dump`; apply with `handflow param load FILE`)\n"
    return head + yaml.safe_dump(nodes, sort_keys=False, default_flow_style=False)  # escaped: a NEL survives


def dump(graph: str, nodes: list[str], ask: Ask, file: str | None, timeout: float) -> int:
    """Write the parameter file (exit 1 when a node of the graph did not answer: the file lacks it)."""
    replies = ask("*", {"op": "get"}, timeout)
    failed = [r for r in replies if not r.get("ok")]
    for r in failed:
        print(f"error: {r.get('error', 'refused')}", file=sys.stderr)
    if failed or not replies:
        return 2 if not replies else max(int(r.get("code", 2)) for r in failed)
    missing = sorted(set(nodes) - {r["node"] for r in replies})
    if missing:
        print(
            f"warning: node(s) {', '.join(missing)} did not answer and are not in the file (not running, or run by "
            "another machine's launcher: join its hub with --connect)",
            file=sys.stderr,
        )
    text = dump_text(graph, replies)
    if file is None:
        sys.stdout.write(text)
        return 1 if missing else 0
    try:
        Path(file).write_text(text)
    except OSError as exc:
        print(f"error: cannot write {file}: {exc.strerror}; pass a writable path", file=sys.stderr)
        return 2
    print(f"wrote the parameters of {len(replies)} node(s) of graph '{graph}' to {file}", file=sys.stderr)
    return 1 if missing else 0


def _unknown(
    wanted: dict[str, dict[str, Any]], current: dict[str, dict[str, Any]], graph: str, nodes: list[str], file: str
) -> list[str]:
    problems = []
    for node, params in wanted.items():
        if node not in current:
            problems.append(
                f"{file}: node '{node}' of graph '{graph}' did not answer: is it running? (see the graph's log)"
                if node in nodes
                else f"{file}: graph '{graph}' has no node '{node}' (its nodes: {', '.join(sorted(nodes))})"
            )
            continue
        for key in params.keys() - current[node]["params"].keys():
            problems.append(
                f"{file}: node '{node}' has no parameter '{key}' (it has: {', '.join(current[node]['params'])})"
            )
    return problems


def load(graph: str, nodes: list[str], ask: Ask, file: str, restart: bool, timeouts: tuple[float, float]) -> int:
    """Apply ``file`` to the running graph (see the module docstring); exit code as ``param set``."""
    node_timeout, restart_timeout = timeouts
    try:
        wanted = read_param_file(Path(file).read_text(), file)
    except OSError as exc:
        print(f"error: cannot read {file}: {exc.strerror}", file=sys.stderr)
        return 2
    except (ParamFileError, UnicodeDecodeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    current = {r["node"]: r for r in ask("*", {"op": "get"}, node_timeout) if r.get("ok")}
    if problems := _unknown(wanted, current, graph, nodes or sorted(current), file):
        print("\n".join(f"error: {p}" for p in problems) + "\nnothing changed", file=sys.stderr)
        return 2
    codes, applied, unchanged = [], 0, 0
    for node, params in wanted.items():
        now, live = current[node]["params"], set(current[node].get("live", []))
        changed = {k: v for k, v in params.items() if not same_value(v, now[k])}
        unchanged += len(params) - len(changed)
        batch = {k: v for k, v in changed.items() if k not in live} if restart else {}
        requests = [{"op": "set", "key": k, "value": v, "restart": False} for k, v in changed.items() if k not in batch]
        if batch:
            requests.append({"op": "set", "values": batch, "restart": True})
        for request in requests:
            replies = ask(node, request, restart_timeout if request["restart"] else node_timeout)
            reply = replies[0] if replies else {"ok": False, "code": 2, "error": f"node '{node}' did not answer"}
            keys = list(request.get("values", [request.get("key")]))
            if not reply.get("ok"):
                print(f"error: {reply.get('error', 'refused')}", file=sys.stderr)
                codes.append(int(reply.get("code", 1)))
                continue
            for key in keys:
                print(f"{node}.{key} = {show(reply['params'][key])}{'  (restarted)' if request['restart'] else ''}")
            applied += len(keys)
    refused = len(codes)
    print(
        f"loaded {file} into graph '{graph}': {applied} changed key(s) applied, {refused} request(s) refused, "
        f"{unchanged} key(s) already at their value",
        file=sys.stderr,
    )
    return max(codes, default=0)


def show(value: Any) -> str:
    """A parameter value as one would write it in the graph file (``3`` for 3.0)."""
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return value if isinstance(value, str) else json.dumps(value)
