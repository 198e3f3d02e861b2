"""Zenoh transport: key expressions and session configuration (docs/architecture.md).

Keys are ``handflow/<graph>/<node>/<port>``; runtime-internal topics use ports starting with ``_``
(``_health``, ``_progress``) and the graph-wide ``handflow/<graph>/_clock``.

Default topology: the launcher opens a *hub* session (an embedded Zenoh peer listening on a free
loopback port, multicast scouting off, no router); every node process is a peer that connects to
the hub and finds the other peers through gossip.  A graph's ``zenoh.listen`` / ``zenoh.connect``
endpoints are added to the hub so graphs on several machines join one Zenoh network.  With
``zenoh.tls`` the hub is a router speaking mutual TLS to other machines, with access control derived
from the graph (:mod:`handflow.framework.access`), and node processes are its clients.
"""

from __future__ import annotations

import json
import socket

import zenoh

from .graph import ZenohSettings

PREFIX = "handflow"


def topic_key(graph: str, node: str, port: str) -> str:
    return f"{PREFIX}/{graph}/{node}/{port}"


def clock_key(graph: str) -> str:
    return f"{PREFIX}/{graph}/_clock"


def start_key(graph: str) -> str:
    """The launcher's start signal: nodes tick only once every node of the graph has reported ready."""
    return f"{PREFIX}/{graph}/_start"


def events_key(graph: str) -> str:
    """Where the runtime publishes :class:`handflow.framework.messages.RuntimeEvent` messages."""
    return f"{PREFIX}/{graph}/_runtime/events"


def split_key(key: str) -> tuple[str, str, str] | None:
    """``handflow/<graph>/<node>/<port>`` → (graph, node, port), else None."""
    parts = str(key).split("/")
    if len(parts) != 4 or parts[0] != PREFIX:
        return None
    return parts[1], parts[2], parts[3]


def free_tcp_port(host: str = "127.0.0.1") -> int:
    with socket.socket() as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def _config(mode: str, listen: list[str], connect: list[str], multicast: bool) -> zenoh.Config:
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("scouting/multicast/enabled", json.dumps(multicast))
    conf.insert_json5("scouting/gossip/enabled", "true")
    conf.insert_json5("listen/endpoints", json.dumps(listen))
    conf.insert_json5("connect/endpoints", json.dumps(connect))
    # keep retrying the hub instead of failing when a node starts slightly before it
    conf.insert_json5("connect/timeout_ms", "-1")
    return conf


class EndpointInUse(OSError):
    """A ``zenoh.listen`` endpoint whose address is taken by another program."""


def open_hub(settings: ZenohSettings, hub_endpoint: str, secure: dict[str, object] | None = None) -> zenoh.Session:
    """The launcher's session: listens on ``hub_endpoint`` plus the graph's endpoints.

    ``secure`` (``{"tls": ..., "access_control": ...}`` from :mod:`handflow.framework.access`) makes
    the hub a TLS router.  A listen endpoint already in use raises :class:`EndpointInUse` saying
    what to change.
    """
    mode = "router" if secure else settings.mode
    conf = _config(mode, [hub_endpoint, *settings.listen], list(settings.connect), settings.multicast_scouting)
    for key, value in (secure or {}).get("tls", {}).items():
        conf.insert_json5(f"transport/link/tls/{key}", json.dumps(value))
    if secure:
        conf.insert_json5("access_control", json.dumps(secure["access_control"]))
    try:
        return zenoh.open(conf)
    except zenoh.ZError as exc:
        busy = [ep for ep in settings.listen if ep.split("/", 1)[-1] in str(exc)]
        if "in use" not in str(exc).lower() or not busy:
            raise
        raise EndpointInUse(
            f"cannot listen on {busy[0]}: the address is already in use (another `handflow run` of "
            f"this graph, or another program); stop that program or choose a free port in the "
            f"graph's 'zenoh: {{listen: [...]}}'"
        ) from None


def open_node_session(settings: ZenohSettings, hub_endpoint: str) -> zenoh.Session:
    """A node process's session: a peer connected to the local hub.

    It listens on an ephemeral port of the interface the graph listens on (loopback by default) so
    gossip can connect peers directly.  In a TLS graph it is a client of the hub (a router) and
    listens nowhere, so every message to or from another machine passes the hub's access control.
    """
    if settings.tls is not None:
        return zenoh.open(_config("client", [], [hub_endpoint], False))
    host = "127.0.0.1"
    for ep in settings.listen:
        proto, _, addr = ep.partition("/")
        if proto == "tcp" and addr:
            host = addr.rsplit(":", 1)[0]
            break
    return zenoh.open(_config("peer", [f"tcp/{host}:0"], [hub_endpoint], settings.multicast_scouting))


def open_tls_client(endpoint: str, ca: object, cert: object, key: object, timeout_s: float = 10.0) -> zenoh.Session:
    """A client of a TLS graph's hub from another machine (monitor, record, replay) with its own certificate.

    A client, not a peer: it joins no peer mesh, so everything it reads or writes passes the hub's
    access control.  ``enable_mtls`` matters on this side too: without it Zenoh does not present the
    certificate and the hub refuses the link.  Raises ``zenoh.ZError`` when no link is accepted within
    ``timeout_s`` (hub unreachable, or the certificate refused).
    """
    conf = _config("client", [], [endpoint], False)
    conf.insert_json5("connect/timeout_ms", json.dumps(int(timeout_s * 1000)))
    tls = {"root_ca_certificate": str(ca), "connect_certificate": str(cert), "connect_private_key": str(key)}
    for k, v in {**tls, "enable_mtls": True, "verify_name_on_connect": False}.items():
        conf.insert_json5(f"transport/link/tls/{k}", json.dumps(v))
    return zenoh.open(conf)


def hub_endpoint_for(port: int | None = None) -> str:
    return f"tcp/127.0.0.1:{port or free_tcp_port()}"
