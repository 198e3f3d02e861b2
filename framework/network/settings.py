"""Zenoh and local-transport settings of a graph file: endpoints, TLS and user/password (docs/architecture.md, docs/security.md).

The graph model and the sessions both use them, so neither imports the other.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from ..files.params import StrictModel


class TlsSettings(StrictModel):
    """Mutual TLS between the graph's machines; access rights derived from the graph (docs/security.md)."""

    certs: str = Field(description="directory made by `handflow certs init`, relative to the graph file")
    host: str | None = Field(None, description="this machine's certificate name (default: `handflow run --host`)")
    readers: list[str] = Field(
        default_factory=list, description="certificate names that may read every topic (monitor, record, replay)"
    )
    operators: list[str] = Field(
        default_factory=list,
        description="certificate names that may change parameters while the graph runs, besides its hosts "
        "(`handflow param set`, docs/tuning.md)",
    )
    publishers: dict[str, list[str]] = Field(
        default_factory=dict, description="external topic (node/port) → certificate names that may publish it"
    )


class UsrPwdSettings(StrictModel):
    """Zenoh user/password authentication on every link of the graph (docs/security.md)."""

    credentials: str = Field(description="file of 'user:password' lines, relative to the graph file")
    user: str | None = Field(
        None, description="this machine's user (default: `handflow run --host`, else the only one)"
    )


class ZenohSettings(StrictModel):
    """Transport settings. Default: embedded peer on loopback, multicast scouting off, no router."""

    mode: Literal["peer", "client"] = "peer"
    listen: list[str] = Field(
        default_factory=list, description="extra endpoints this graph listens on, e.g. tcp/0.0.0.0:7450"
    )
    connect: list[str] = Field(
        default_factory=list, description="endpoints of other machines' graphs, e.g. tcp/192.168.1.7:7450"
    )
    multicast_scouting: bool = False
    tls: TlsSettings | None = Field(None, description="mutual TLS and generated access control (docs/security.md)")
    usrpwd: UsrPwdSettings | None = Field(None, description="user/password authentication (docs/security.md)")
    insecure: bool = Field(False, description="allow plain endpoints beyond loopback (anyone who reaches them joins)")
    shared_memory: bool = Field(
        True, description="large payloads between processes on this host through shared memory (docs/shared_memory.md)"
    )


class TransportSettings(StrictModel):
    """How node processes of one graph host reach each other (docs/shared_memory.md)."""

    local: Literal["iceoryx2", "zenoh"] = Field(
        "iceoryx2", description="iceoryx2: zero-copy shared memory between this host's processes; zenoh: Zenoh only"
    )


def is_loopback_endpoint(endpoint: str) -> bool:
    """``tcp/127.0.0.1:7447``, ``tcp/localhost:0``, ``tcp/[::1]:7447`` → True; other addresses → False."""
    addr = endpoint.partition("/")[2].split("#", 1)[0]
    host = addr.rsplit(":", 1)[0].strip("[]")
    return host == "localhost" or host.startswith("127.") or host == "::1"
