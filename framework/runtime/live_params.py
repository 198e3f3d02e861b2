"""Live parameters inside a node process (docs/tuning.md).

Each node answers its launcher's requests (:mod:`.param_service`) on
``handflow/<graph>/<node>/_params``, a JSON object with ``op``:

- ``get``: the node's applied params, which of them are live, its plugin;
- ``set`` (``key``, ``value``, ``restart``): the value is validated by the plugin's ``Params`` model as at
  start; a live key is handed to :meth:`handflow.framework.plugin.Node.on_params` under the runtime's
  lock (never while another hook of the process runs); a key not marked live is refused with "needs a
  restart"; with ``restart`` any key is only checked, for the launcher to restart the node with it.

Requests arrive on a Zenoh session of their own, so they do not queue behind the data the node's
session is busy delivering (a segmenter fed 40 frames a second answered a request only after
seconds on the shared link); a ``set`` waits at most for the hook running at that moment.

An accepted change is kept in the run's state folder (``params-<node>.json``), so the node's next
process (a restart, also after a crash) starts with it, and is published as a
:class:`~handflow.framework.messages.ParamChange` on ``handflow/<graph>/_params/changes`` stamped with
the first input (or tick) the node handles with the new value.
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from pydantic import BaseModel, ValidationError

from .. import keys, wire
from ..files.params import live_keys
from ..messages import Header, ParamChange

if TYPE_CHECKING:
    from ..graphs.model import Graph, ResolvedNode
    from ..plugin import Node

log = logging.getLogger("handflow.params")


class ParamSlot(Protocol):
    """One node of a node process, as its parameter service sees it."""

    id: str
    node: Node
    rn: ResolvedNode
    ctx: Any  # the node's context: its ``log``


class ParamRuntime(Protocol):
    """What :class:`NodeParams` needs of the node process that runs it (the runner's ``GroupRuntime``)."""

    graph: Graph
    session: Any  # the process's Zenoh session
    slots: Sequence[ParamSlot]

    @property
    def lock(self) -> threading.Lock:
        """Held while a hook of a node runs: node code never runs concurrently with itself."""

    def now_ns(self) -> int: ...


class ParamRefused(ValueError):
    """A parameter request the node does not accept; the text says why and what to do.  ``code``: the exit
    code of ``handflow param`` (1 a refused value, 2 a request naming no parameter)."""

    def __init__(self, text: str, code: int = 1) -> None:
        super().__init__(text)
        self.code = code


def overrides_file(state_dir: Path, node: str) -> Path:
    return Path(state_dir) / f"params-{node}.json"


def save_override(state_dir: Path | None, node: str, key: str, value: Any) -> None:
    """Keep ``node.key = value`` for the node's next process in this run (written atomically)."""
    if state_dir is None:
        return
    path = overrides_file(state_dir, node)
    values = json.loads(path.read_text()) if path.exists() else {}
    values[key] = value
    _write_overrides(path, values)


def _write_overrides(path: Path, values: dict[str, Any]) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(values))
    tmp.replace(path)


def forget_edited_params(state_dir: Path, old: Graph, new: Graph) -> None:
    """After an edit of the graph file or of a plugin (``handflow run --watch``): the file's value wins for
    every key the edit changed in a node's ``params:``, and for a value the edited plugin's ``Params``
    refuses (logged); the changes set while running are kept for the other keys; a node the edit
    removed forgets them all (docs/tuning.md, "Editing a running graph")."""
    for nid, rn in old.nodes.items():
        path = overrides_file(state_dir, nid)
        if not path.exists():
            continue
        if nid not in new.nodes:
            path.unlink()
            continue
        before, after = rn.spec.params, new.nodes[nid].spec.params
        edited = {k for k in before.keys() | after.keys() if before.get(k) != after.get(k)}
        values = {}
        for key, value in json.loads(path.read_text()).items():
            if key in edited:
                continue
            try:
                validated(new.nodes[nid].params, nid, key, value)
            except ParamRefused as exc:
                log.warning("%s by the edited plugin; node '%s' starts with the graph file's value", exc, nid)
                continue
            values[key] = value
        _write_overrides(path, values)


def apply_overrides(graph: Graph, node_ids: list[str], state_dir: Path | None) -> None:
    """Start the nodes with the changes accepted earlier in this run (before their restart)."""
    for nid in node_ids:
        path = overrides_file(state_dir, nid) if state_dir else None
        if path is None or not path.exists():
            continue
        rn = graph.nodes[nid]
        rn.params = type(rn.params).model_validate({**dict(rn.params), **json.loads(path.read_text())})
        log.info("node '%s' starts with the parameters set while the graph ran: %s", nid, path.read_text())


def validated(params: BaseModel, node: str, key: str, value: Any) -> BaseModel:
    """``params`` with ``key = value``, validated by its model; :class:`ParamRefused` with the model's message."""
    fields = type(params).model_fields
    if key not in fields:
        raise ParamRefused(f"node '{node}' has no parameter '{key}' (it has: {', '.join(fields) or 'none'})", code=2)
    try:
        return type(params).model_validate({**dict(params), key: value})
    except ValidationError as exc:
        problems = "; ".join(
            f"{'.'.join(str(p) for p in e['loc']) or key}: {e['msg']}" for e in exc.errors(include_url=False)
        )
        raise ParamRefused(f"{node}.{key} = {json.dumps(value)} refused: {problems}") from None


def take(node: Node, node_id: str, plugin: str, key: str, value: Any) -> BaseModel:
    """Hand ``key = value`` to a running ``node`` (validated; :meth:`Node.on_params`) and return its old
    params; :class:`ParamRefused` when the key is not live or the value fails, the old params kept."""
    old = node.params
    new = validated(old, node_id, key, value)
    if key not in live_keys(type(old)):
        raise ParamRefused(
            f"{node_id}.{key} needs a restart: {plugin} does not take it while running "
            f"(pass --restart to restart node '{node_id}' with it)"
        )
    try:
        node.on_params(new, frozenset({key}))
    except (ValueError, OSError) as exc:  # e.g. a calibration file that does not load
        node.params = old
        raise ParamRefused(f"{node_id}.{key} = {json.dumps(value)} refused by the node: {exc}") from None
    return old


def describe(params: BaseModel, plugin: str) -> dict[str, Any]:
    """A node's answer to ``get``: its params as JSON, its live keys, its plugin."""
    return {
        "ok": True,
        "plugin": plugin,
        "params": params.model_dump(mode="json"),
        "live": sorted(live_keys(type(params))),
    }


class NodeParams:
    """The parameter service of one node process (see the module docstring)."""

    def __init__(
        self, rt: ParamRuntime, node_ids: list[str], state_dir: Path | None, open_session: Callable[[], Any]
    ) -> None:
        self._rt = rt
        self._state_dir = state_dir
        self._open_session = open_session
        self._session = None
        self._pending: dict[str, list[ParamChange]] = {}
        self._queryables: list[Any] = []
        self._pub = None
        apply_overrides(rt.graph, node_ids, state_dir)

    def declare(self) -> None:
        """Answer requests (once the nodes are set up)."""
        g = self._rt.graph.name
        self._pub = self._rt.session.declare_publisher(keys.params_key(g))
        self._session = self._open_session()
        for slot in self._rt.slots:
            self._queryables.append(
                self._session.declare_queryable(
                    keys.node_params_key(g, slot.id), lambda query, s=slot: self._on_query(s, query)
                )
            )

    def _on_query(self, slot: ParamSlot, query: Any) -> None:
        try:
            request = json.loads(query.payload.to_bytes()) if query.payload is not None else {}
            reply = self.handle(slot, request)
        except ParamRefused as exc:
            reply = {"ok": False, "code": exc.code, "error": str(exc)}
        except (ValueError, TypeError, AttributeError, KeyError) as exc:  # a malformed request
            reply = {"ok": False, "code": 2, "error": f"bad parameter request: {exc}"}
        query.reply(query.key_expr, json.dumps(reply))

    def handle(self, slot: ParamSlot, request: dict[str, Any]) -> dict[str, Any]:
        """Answer one request (``get`` or ``set``) for the node of ``slot``."""
        op = request.get("op")
        if op == "get":  # params are replaced whole, never changed in place: no need to wait for the lock
            return describe(slot.node.params, slot.rn.spec.plugin)
        if op != "set":
            raise ParamRefused(f"unknown parameter request {op!r}: get or set", code=2)
        if "values" in request:  # several keys at once, checked only: the launcher restarts the node with them
            new = slot.node.params
            for key, value in dict(request["values"]).items():
                new = validated(new, slot.id, str(key), value)
            return {**describe(new, slot.rn.spec.plugin), "restart": True}
        key, value = str(request["key"]), request.get("value")
        with self._rt.lock:
            if request.get("restart"):  # checked only: the launcher restarts the node with it
                new = validated(slot.node.params, slot.id, key, value)
                return {**describe(new, slot.rn.spec.plugin), "restart": True}
            old = take(slot.node, slot.id, slot.rn.spec.plugin, key, value)
            slot.rn.params = slot.node.params
            applied = slot.node.params.model_dump(mode="json")
            change = ParamChange(
                node=slot.id,
                key=key,
                value=json.dumps(applied[key]),
                previous=json.dumps(old.model_dump(mode="json")[key]),
            )
            self._pending.setdefault(slot.id, []).append(change)
        save_override(self._state_dir, slot.id, key, applied[key])
        slot.ctx.log.info("%s = %s (was %s)", key, change.value, change.previous)
        return describe(slot.node.params, slot.rn.spec.plugin)

    def handling(self, node: str, stamp_ns: int) -> None:
        """The node is about to handle an input (or tick) stamped ``stamp_ns``: publish the changes it is
        the first to see (called under the runtime's lock)."""
        if node in self._pending:
            for change in self._pending.pop(node):
                self._publish(change, stamp_ns)

    def _publish(self, change: ParamChange, stamp_ns: int) -> None:
        change.header = Header(change.node, 0, stamp_ns)  # seq 0: several processes publish on the topic
        payload, att = wire.pack(change)
        self._pub.put(payload, attachment=att)

    def close(self) -> None:
        """Publish the changes no input saw (stamped now), stop answering."""
        for node in list(self._pending):
            self.handling(node, self._rt.now_ns())
        for queryable in self._queryables:
            queryable.undeclare()
        if self._session is not None:
            self._session.close()
        if self._pub is not None:
            self._pub.undeclare()
