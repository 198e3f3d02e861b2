"""Which graphs a hub serves: each launcher's hub answers queries on ``handflow/<graph>/_runtime/info``.

A reader (monitor, record, Foxglove bridge) that joins a hub with ``--connect`` asks
``handflow/*/_runtime/info`` and learns the graphs there, then subscribes to each graph's topics;
no answer means it reached no graph (or its certificate is not granted), which the commands report
as an error (docs/monitoring.md, "Watching from another machine").  In a TLS graph only readers may
ask (:mod:`handflow.framework.security.access`).
"""

from __future__ import annotations

import json
from typing import Any

from ..keys import PREFIX

ANY_GRAPH = "*"


def info_key(graph: str) -> str:
    return f"{PREFIX}/{graph}/_runtime/info"


def declare_info(session: Any, graph: str, host: str | None, nodes: list[str], external: list[str] = ()) -> Any:
    """The hub's queryable: replies ``{"graph", "host", "nodes", "external"}`` (``nodes``: all of the graph's
    nodes; ``external``: the ``node/port`` topics fed from outside it, e.g. the cues of ``handflow collect``)."""
    payload = json.dumps({"graph": graph, "host": host, "nodes": sorted(nodes), "external": sorted(external)})
    return session.declare_queryable(info_key(graph), lambda query: query.reply(info_key(graph), payload))


def graphs_on(session: Any, graph: str = ANY_GRAPH, timeout_s: float = 2.0) -> dict[str, dict[str, Any]]:
    """The graphs whose hubs answer on ``session`` (name → the first hub's reply), within ``timeout_s``."""
    found: dict[str, dict[str, Any]] = {}
    for reply in session.get(info_key(graph), timeout=timeout_s):
        if reply.ok is None:
            continue
        try:
            info = json.loads(reply.ok.payload.to_bytes())
            found.setdefault(str(info["graph"]), info)
        except (ValueError, KeyError, TypeError):
            continue
    return found
