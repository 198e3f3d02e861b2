"""Zenoh transport: key expressions and session configuration (docs/architecture.md).

Keys are ``handflow/<graph>/<node>/<port>``; runtime-internal topics use ports starting with ``_``
(``_health``, ``_progress``) and the graph-wide ``handflow/<graph>/_clock``.

Default topology: the launcher opens a *hub* session (an embedded Zenoh peer listening on a free
loopback port, multicast scouting off, no router); every node process is a peer that connects to
the hub and finds the other peers through gossip.  A graph's ``zenoh.listen`` / ``zenoh.connect``
endpoints are added to the hub so graphs on several machines join one Zenoh network.  With
``zenoh.tls`` the hub is a router speaking mutual TLS to other machines, with access control derived
from the graph (:mod:`handflow.framework.security.access`), and node processes are its clients.  With
``zenoh.usrpwd`` (alone or with TLS) the hub is a router too, checks every link against the graph's
credentials (:mod:`handflow.framework.security.credentials`), and its node processes log in as clients.
"""

from __future__ import annotations

import json
import socket

import zenoh

from . import shm
from .settings import ZenohSettings


def free_tcp_port(host: str = "127.0.0.1") -> int:
    with socket.socket() as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def _config(
    mode: str, listen: list[str], connect: list[str], multicast: bool, shared_memory: bool = True
) -> zenoh.Config:
    conf = zenoh.Config()
    shm.configure(conf, shared_memory)
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


def _insert(conf: zenoh.Config, prefix: str, values: dict[str, object] | None) -> None:
    for key, value in (values or {}).items():
        conf.insert_json5(f"{prefix}/{key}", json.dumps(value))


def open_hub(settings: ZenohSettings, hub_endpoint: str, secure: dict[str, object] | None = None) -> zenoh.Session:
    """The launcher's session: listens on ``hub_endpoint`` plus the graph's endpoints.

    ``secure`` makes the hub a router: ``"tls"`` and ``"access_control"`` from
    :mod:`handflow.framework.security.access`, ``"usrpwd"`` from :func:`credentials.usrpwd_settings`.  A
    listen endpoint already in use raises :class:`EndpointInUse` saying what to change.
    """
    secure = secure or {}
    mode = "router" if secure else settings.mode
    conf = _config(
        mode,
        [hub_endpoint, *settings.listen],
        list(settings.connect),
        settings.multicast_scouting,
        settings.shared_memory,
    )
    _insert(conf, "transport/link/tls", secure.get("tls"))
    _insert(conf, "transport/auth/usrpwd", secure.get("usrpwd"))
    if "access_control" in secure:
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


def open_node_session(
    settings: ZenohSettings, hub_endpoint: str, usrpwd: dict[str, str] | None = None
) -> zenoh.Session:
    """A node process's session: a peer connected to the local hub.

    It listens on an ephemeral port of the interface the graph listens on (loopback by default) so
    gossip can connect peers directly.  In a TLS or user/password graph it is a client of the hub (a
    router), logs in with ``usrpwd`` and listens nowhere, so every message to or from another
    machine passes the hub's checks.
    """
    if settings.tls is not None or settings.usrpwd is not None:
        conf = _config("client", [], [hub_endpoint], False, settings.shared_memory)
        _insert(conf, "transport/auth/usrpwd", usrpwd)
        return zenoh.open(conf)
    host = "127.0.0.1"
    for ep in settings.listen:
        proto, _, addr = ep.partition("/")
        if proto == "tcp" and addr:
            host = addr.rsplit(":", 1)[0]
            break
    return zenoh.open(
        _config("peer", [f"tcp/{host}:0"], [hub_endpoint], settings.multicast_scouting, settings.shared_memory)
    )


def open_client(
    endpoint: str,
    certificate: tuple[object, object, object] | None = None,
    usrpwd: dict[str, str] | None = None,
    timeout_s: float = 10.0,
) -> zenoh.Session:
    """A client of a secure graph's hub (monitor, record, replay) with its own certificate and/or login.

    A client, not a peer: it joins no peer mesh, so everything it reads or writes passes the hub's
    checks.  ``certificate`` is (CA, certificate, key); ``enable_mtls`` matters on this side too:
    without it Zenoh does not present the certificate and the hub refuses the link.  Raises
    ``zenoh.ZError`` when no link is accepted within ``timeout_s`` (hub unreachable, certificate or
    password refused).
    """
    conf = _config("client", [], [endpoint], False)
    conf.insert_json5("connect/timeout_ms", json.dumps(int(timeout_s * 1000)))
    if certificate is not None:
        ca, cert, key = (str(f) for f in certificate)
        tls = {"root_ca_certificate": ca, "connect_certificate": cert, "connect_private_key": key}
        _insert(conf, "transport/link/tls", {**tls, "enable_mtls": True, "verify_name_on_connect": False})
    _insert(conf, "transport/auth/usrpwd", usrpwd)
    return zenoh.open(conf)


def hub_endpoint_for(port: int | None = None) -> str:
    return f"tcp/127.0.0.1:{port or free_tcp_port()}"
