"""Foxglove's Parameters panel on a running graph: the ``Parameters`` capability of the live view
(docs/tuning.md, docs/foxglove.md).

Every parameter of every node, live or not, is a Foxglove parameter named ``/<node>/<key>``.  Reading
and setting go through the launcher's parameter service (:mod:`handflow.framework.runtime.param_service`)
as ``handflow param`` does, so a value is validated by the node's model and a refused one (invalid, or
a key the node takes only at start) is answered with the node's current value and the reason as an
error status in Foxglove; for a start-only key the reason is the terminal command that applies it.
Changes made elsewhere (``handflow param set``) reach subscribed panels through the graph's parameter
topic.

Values keep their JSON types (``3`` stays an integer, ``3.0`` a float).  Foxglove's protocol has no
null value, so ``null`` is sent as :data:`NULL` (the empty string), also inside lists and mappings;
set back, the empty string (or a JSON ``null``) is ``null`` again unless the key holds a string now.
"""

from __future__ import annotations

import json
import logging
import shlex
from typing import TYPE_CHECKING, Any

try:  # the optional extra 'foxglove'; the bridge says how to install it
    from foxglove.websocket import Parameter, ServerListener, StatusLevel
except ImportError:
    ServerListener = object

from ..commands.param_files import show
from ..keys import param_request_key
from ..messages import ParamChange

if TYPE_CHECKING:
    import foxglove

log = logging.getLogger("handflow.foxglove")
TIMEOUT_S = 5.0
NULL = ""
"""How a ``null`` value travels to Foxglove (docs/foxglove.md, "Parameters")."""


def shown(value: Any) -> Any:
    """A parameter value as Foxglove is sent it: ``null`` as :data:`NULL`, everything else as is."""
    if value is None:
        return NULL
    if isinstance(value, list):
        return [shown(v) for v in value]
    if isinstance(value, dict):
        return {k: shown(v) for k, v in value.items()}
    return value


def parameter(node: str, key: str, value: Any) -> Parameter:
    """The Foxglove parameter ``/<node>/<key>`` with ``value`` (:func:`shown`)."""
    return Parameter(f"/{node}/{key}", value=shown(value))


def taken(value: Any, current: Any) -> Any:
    """A value set from Foxglove as the node is asked to take it: :data:`NULL` is ``null`` unless the key
    holds a string now (then it is the empty string)."""
    if value == NULL and not isinstance(current, str):
        return None
    return value


class ParamsListener(ServerListener):
    """Answers Foxglove's ``getParameters`` / ``setParameters`` for one graph, asking as ``who``."""

    def __init__(self, session: Any, graph: str, who: str) -> None:
        self.session, self.graph, self.who = session, graph, who
        self.server: foxglove.WebSocketServer | None = None  # set once started: refusals are sent as status

    def _ask(self, node: str, request: dict[str, Any]) -> list[dict[str, Any]]:
        key = param_request_key(self.graph, self.who, node)
        return [
            json.loads(r.ok.payload.to_bytes())
            for r in self.session.get(key, payload=json.dumps(request), timeout=TIMEOUT_S)
            if r.ok is not None
        ]

    def on_get_parameters(self, client, param_names: list[str], request_id: str | None = None) -> list[Parameter]:
        wanted = set(param_names)
        return [
            parameter(answer["node"], key, value)
            for answer in self._ask("*", {"op": "get"})
            if answer.get("ok")
            for key, value in answer["params"].items()
            if not wanted or f"/{answer['node']}/{key}" in wanted
        ]

    def on_set_parameters(self, client, parameters: list[Parameter], request_id: str | None = None) -> list[Parameter]:
        applied = []
        for p in parameters:
            node, _, key = p.name.strip("/").partition("/")
            now = (self._ask(node, {"op": "get"}) or [{"ok": False, "error": f"no node '{node}' answered"}])[0]
            answer = self._set(node, key, p.get_value(), now) if now.get("ok") else now
            if not answer.get("ok"):
                self._refused(p.name, answer.get("error", "refused"), request_id)
                answer = now
            if answer.get("ok") and key in answer["params"]:
                applied.append(parameter(node, key, answer["params"][key]))
        return applied

    def _set(self, node: str, key: str, value: Any, now: dict[str, Any]) -> dict[str, Any]:
        """Set ``node.key`` given the node's current answer ``now``; a start-only key is refused with the
        command that restarts the node with it (Foxglove restarts no node)."""
        if key not in now["params"]:
            return {"ok": False, "error": f"node '{node}' has no parameter '{key}'"}
        value = taken(value, now["params"][key])
        if key not in now.get("live", []):
            command = f"handflow param set {node}.{key} {shlex.quote(show(value))} --restart"
            return {"ok": False, "error": f"{node} takes {key} only at start; to restart it with the value: {command}"}
        return (self._ask(node, {"op": "set", "key": key, "value": value}) or [{"ok": False, "error": "no answer"}])[0]

    def _refused(self, name: str, why: str, request_id: str | None) -> None:
        log.warning("Foxglove: %s not set: %s", name, why)
        if self.server is not None:
            self.server.publish_status(f"{name} not set: {why}", StatusLevel.Error, request_id)

    def changed(self, change: ParamChange) -> None:
        """Tell subscribed panels about a change made anywhere (the graph's parameter topic)."""
        if self.server is not None:
            self.server.publish_parameter_values([parameter(change.node, change.key, json.loads(change.value))])
