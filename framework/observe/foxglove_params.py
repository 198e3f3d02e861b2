"""Foxglove's Parameters panel on a running graph: the ``Parameters`` capability of the live view
(docs/tuning.md, docs/foxglove.md).

Every node parameter is a Foxglove parameter named ``/<node>/<key>``.  Reading and setting go through
the launcher's parameter service (:mod:`handflow.framework.runtime.param_service`) as ``handflow
param`` does, so a value is validated by the node's model and a refused one (not live, or invalid) is
answered with the node's current value and the reason as an error status in Foxglove.  Changes
made elsewhere (``handflow param set``) reach subscribed panels through the graph's parameter topic.
"""

from __future__ import annotations

import json
import logging
from typing import TYPE_CHECKING, Any

try:  # the optional extra 'foxglove'; the bridge says how to install it
    from foxglove.websocket import Parameter, ServerListener, StatusLevel
except ImportError:
    ServerListener = object

from ..keys import param_request_key
from ..messages import ParamChange

if TYPE_CHECKING:
    import foxglove

log = logging.getLogger("handflow.foxglove")
TIMEOUT_S = 5.0


def parameter(node: str, key: str, value: Any) -> Parameter:
    """A Foxglove parameter ``/<node>/<key>`` (an unset value for None; numbers as floats)."""
    name = f"/{node}/{key}"
    if value is None:
        return Parameter(name)
    if isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    return Parameter(name, value=value)


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
            value = p.get_value()
            request = {"op": "set", "key": key, "value": value.get_value() if hasattr(value, "get_value") else value}
            answers = self._ask(node, request) or [{"ok": False, "error": f"no node '{node}' answered"}]
            answer = answers[0]
            if not answer.get("ok"):
                self._refused(p.name, answer.get("error", "refused"), request_id)
                answer = (self._ask(node, {"op": "get"}) or [{}])[0]
            if answer.get("ok") and key in answer["params"]:
                applied.append(parameter(node, key, answer["params"][key]))
        return applied

    def _refused(self, name: str, why: str, request_id: str | None) -> None:
        log.warning("Foxglove: %s not set: %s", name, why)
        if self.server is not None:
            self.server.publish_status(f"{name} not set: {why}", StatusLevel.Error, request_id)

    def changed(self, change: ParamChange) -> None:
        """Tell subscribed panels about a change made anywhere (the graph's parameter topic)."""
        if self.server is not None:
            self.server.publish_parameter_values([parameter(change.node, change.key, json.loads(change.value))])
