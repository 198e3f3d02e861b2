"""The launcher's parameter service: ``handflow param`` and Foxglove reach a running graph's nodes here
(docs/tuning.md).

The launcher answers JSON requests on ``handflow/<graph>/_params/<who>/<node>`` for each node it runs
(:func:`handflow.framework.keys.param_request_key`; ``<node>`` ``*`` in a request: every node) and
forwards them to the node's process (:mod:`.live_params`).  ``get`` returns the node's applied
params; ``set`` its answer, and for a key the node takes only at start with ``restart``, the
launcher restarts that node's process alone with the new value and answers once it runs again
(``values`` instead of ``key`` and ``value``: several keys, checked together, one restart;
``handflow param load --restart``).
Every accepted change is on ``handflow/<graph>/_params/changes`` (published by the node, or here
after a restart).

In a TLS graph ``<who>`` is the asker's certificate name, held to it by the hub's access control
(:mod:`handflow.framework.security.access`): the graph's hosts and ``zenoh.tls.operators`` may set,
readers may only get; a refused request is logged here and answered with ``code`` 2.
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from typing import TYPE_CHECKING, Any

from .. import keys, wire
from ..messages import Header, ParamChange
from .live_params import save_override

if TYPE_CHECKING:
    from ..graphs.model import Graph
    from .supervisor import ParamHost

log = logging.getLogger("handflow.params")

LOCAL = "local"  # who asks over the hub's loopback link (trusted), or anyone in a graph without TLS
NODE_TIMEOUT_S = 2.0  # a running node answers within this
RESTART_TIMEOUT_S = 60.0  # a restarted node reports ready within this


def setters(graph: Graph) -> frozenset[str] | None:
    """Who may set parameters: None (anyone who reaches the hub) unless the graph uses TLS."""
    tls = graph.spec.zenoh.tls
    if tls is None:
        return None
    hosts = {rn.spec.host for rn in graph.nodes.values() if rn.spec.host}
    return frozenset({LOCAL, *hosts, *tls.operators, *([tls.host] if tls.host else [])})


class ParamService:
    """Serves parameter requests for the nodes a launcher runs (see the module docstring)."""

    def __init__(self, launcher: ParamHost) -> None:
        self._launcher = launcher
        self._session = launcher.session
        self._graph = launcher.graph.name
        self._setters = setters(launcher.graph)
        self._changes = self._session.declare_publisher(keys.params_key(self._graph))
        self._work: queue.SimpleQueue = queue.SimpleQueue()  # answered in order, off Zenoh's threads
        self._worker = threading.Thread(target=self._serve, name="param-service", daemon=True)
        self._worker.start()
        self._queryables: dict[str, Any] = {}
        self.serve([nid for unit in launcher.units for nid in unit.node_ids])

    def serve(self, node_ids: list[str]) -> None:
        """Answer for these nodes (the ones the launcher runs; they change with ``handflow run --watch``)."""
        for nid in self._queryables.keys() - set(node_ids):
            self._queryables.pop(nid).undeclare()
        for nid in node_ids:
            if nid not in self._queryables:
                self._queryables[nid] = self._session.declare_queryable(
                    keys.param_request_key(self._graph, "*", nid), lambda query, nid=nid: self._work.put((nid, query))
                )

    def _serve(self) -> None:
        while (item := self._work.get()) is not None:
            nid, query = item
            who = str(query.key_expr).split("/")[3]
            try:
                reply = self.answer(nid, who, json.loads(query.payload.to_bytes()))
            except (ValueError, TypeError, AttributeError, KeyError) as exc:
                reply = {"ok": False, "code": 2, "error": f"bad parameter request: {exc}"}
            query.reply(keys.param_request_key(self._graph, who, nid), json.dumps({**reply, "node": nid}))
            query.drop()

    def answer(self, nid: str, who: str, request: dict[str, Any]) -> dict[str, Any]:
        """The answer to one request from ``who`` for node ``nid`` (``values``: several keys, one restart)."""
        if request.get("op") != "set":
            return self._ask(nid, {"op": "get"})
        values = dict(request["values"]) if "values" in request else {str(request["key"]): request.get("value")}
        if self._setters is not None and who not in self._setters:
            named = ", ".join(f"{nid}.{key}" for key in values)
            log.warning("refused: '%s' may not set %s (not a host nor in 'zenoh.tls.operators')", who, named)
            return {
                "ok": False,
                "code": 2,
                "error": f"certificate '{who}' may not change parameters of graph '{self._graph}': only its hosts "
                f"and the certificates in 'zenoh.tls.operators' may (docs/security.md)",
            }
        if "values" in request:
            ask = {"op": "set", "values": values, "restart": True}
        else:
            ask = {"op": "set", "key": next(iter(values)), "value": request.get("value")}
            ask["restart"] = request.get("restart", False)
        reply = self._ask(nid, ask)
        if not (reply.get("ok") and reply.get("restart")):
            return reply
        return self._restart(nid, {key: reply["params"][key] for key in values})

    def _ask(self, nid: str, request: dict[str, Any]) -> dict[str, Any]:
        """Forward ``request`` to the node's process and return its answer."""
        for answer in self._session.get(
            keys.node_params_key(self._graph, nid), payload=json.dumps(request), timeout=NODE_TIMEOUT_S
        ):
            if answer.ok is not None:
                return json.loads(answer.ok.payload.to_bytes())
        return {"ok": False, "error": f"node '{nid}' did not answer: it is not running (see the graph's log)"}

    def _restart(self, nid: str, values: dict[str, Any]) -> dict[str, Any]:
        """Restart the process of ``nid`` (and the nodes of its group) once with ``key = value`` for each of ``values``."""
        launcher = self._launcher
        unit = next(u for u in launcher.units if nid in u.node_ids)
        before = self._ask(nid, {"op": "get"}).get("params", {})
        for key, value in values.items():
            save_override(launcher.state_dir, nid, key, value)
        restarted = threading.Event()
        why = f"parameter {', '.join(f'{nid}.{key}' for key in values)} changed"
        launcher.call_soon(lambda: (launcher.restart(unit, why), restarted.set()))
        deadline = time.monotonic() + RESTART_TIMEOUT_S
        if not restarted.wait(RESTART_TIMEOUT_S) or not _wait(lambda: launcher.ready(unit), deadline):
            return {"ok": False, "error": f"node '{nid}' did not come back within {RESTART_TIMEOUT_S:.0f}s"}
        reply = self._ask(nid, {"op": "get"})
        if reply.get("ok"):
            for key, value in values.items():
                self._publish(
                    ParamChange(
                        node=nid, key=key, value=json.dumps(value), previous=json.dumps(before.get(key)), restart=True
                    )
                )
        return reply

    def _publish(self, change: ParamChange) -> None:
        change.header = Header("_launcher", 0, time.time_ns())  # seq 0: the nodes publish on the topic too
        payload, att = wire.pack(change)
        self._changes.put(payload, attachment=att)

    def close(self) -> None:
        for queryable in self._queryables.values():
            queryable.undeclare()
        self._work.put(None)
        self._worker.join(timeout=NODE_TIMEOUT_S)
        self._changes.undeclare()


def _wait(predicate, deadline: float) -> bool:
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True
