"""Zenoh TLS and access-control settings derived from a graph (docs/security.md).

The hub of a secure graph is a Zenoh router: its own node processes reach it over loopback TCP
(trusted, all rights); other machines reach it only over mutual TLS and are identified by the
common name of their certificate (= the host name of ``handflow certs add-host``).  A host may
publish only the outputs of its own nodes (and the external topics naming it in
``zenoh.tls.publishers``) and receives only what its nodes consume plus the runtime's health and
progress topics; ``zenoh.tls.readers`` receive everything and publish nothing, and may ask which
graphs the hub serves (:mod:`handflow.framework.network.hub_info`).  ``zenoh.tls.operators`` may ask that
too; readers, operators and the other hosts may send parameter requests to the hub, each only under its own
certificate name (``handflow/<graph>/_params/<name>/*``), so the hub's parameter service knows who asks and
lets only hosts and operators set (:mod:`handflow.framework.runtime.param_service`).  A graph with readers lets every host
receive every topic of the graph, since a reader may join any hub and that hub relays the other
machines' topics to it; Zenoh routes by declared subscriptions, so a topic still crosses a link only
while someone on the far side subscribes to it.  Everything else, including a valid certificate of
an unknown host, is denied.
"""

from __future__ import annotations

from pathlib import Path

from ..graphs.model import Graph
from ..keys import PREFIX, events_key, param_request_key, topic_key
from ..network.hub_info import ANY_GRAPH, info_key
from .certs import check_host_files

ALL_MESSAGES = [
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "reply",
    "declare_queryable",
    "liveliness_token",
    "liveliness_query",
    "declare_liveliness_subscriber",
]
_DECLARE = ["declare_subscriber", "liveliness_token", "declare_liveliness_subscriber"]


def certificate_dir(graph: Graph) -> Path:
    tls = graph.spec.zenoh.tls
    assert tls is not None
    return (graph.base_dir / tls.certs).resolve()


def tls_settings(graph: Graph, host: str | None) -> dict[str, object]:
    """``transport/link/tls/*`` values for this machine's certificate (checked first: clear errors)."""
    tls = graph.spec.zenoh.tls
    assert tls is not None
    name = tls.host or host
    if not name:
        raise ValueError(
            f"graph '{graph.name}' uses TLS: say which certificate this machine uses with `handflow run --host NAME` "
            f"or 'zenoh: {{tls: {{host: NAME}}}}'"
        )
    ca, cert, key = check_host_files(certificate_dir(graph), name)
    return {
        "root_ca_certificate": str(ca),
        "listen_certificate": str(cert),
        "listen_private_key": str(key),
        "connect_certificate": str(cert),
        "connect_private_key": str(key),
        "enable_mtls": True,
        "verify_name_on_connect": False,  # peers are authenticated by the CA and their common name
        "close_link_on_expiration": True,
    }


def _rule(rule_id: str, messages: list[str], flow: str, keys: list[str]) -> dict[str, object]:
    return {"id": rule_id, "messages": messages, "flows": [flow], "permission": "allow", "key_exprs": sorted(set(keys))}


def access_control(graph: Graph, host: str | None) -> dict[str, object]:
    """The hub's ``access_control`` section: rights of each other host, derived from the graph."""
    tls = graph.spec.zenoh.tls
    assert tls is not None
    g = graph.name
    me = tls.host or host
    runtime = [topic_key(g, nid, port) for nid in graph.nodes for port in ("_health", "_progress")]
    runtime.append(events_key(g))
    hosts = sorted({rn.spec.host for rn in graph.nodes.values() if rn.spec.host and rn.spec.host != me})
    hosts += sorted({h for names in tls.publishers.values() for h in names} - set(hosts) - {me})
    rules = [_rule("local", ALL_MESSAGES, "ingress", ["**"]), _rule("local-out", ALL_MESSAGES, "egress", ["**"])]
    subjects: list[dict[str, object]] = [{"id": "local", "link_protocols": ["tcp"]}]
    policies = [{"rules": ["local", "local-out"], "subjects": ["local"]}]
    for h in hosts:
        own = [nid for nid, rn in graph.nodes.items() if rn.spec.host == h]
        publishes = [f"{PREFIX}/{g}/{nid}/**" for nid in own]
        publishes += [f"{PREFIX}/{g}/{t}" for t, names in tls.publishers.items() if h in names]
        publishes += [events_key(g)]
        consumes = [f"{PREFIX}/{g}/{src}" for nid in own for src in graph.nodes[nid].spec.inputs.values()]
        receives = [f"{PREFIX}/{g}/**"] if tls.readers else consumes + runtime  # its hub relays to readers
        rules += [
            _rule(f"{h}-publish", ["put"], "ingress", publishes),
            _rule(f"{h}-declare", _DECLARE, "ingress", [f"{PREFIX}/{g}/**"]),
            _rule(f"{h}-receive", ["put"], "egress", receives),
            _rule(f"{h}-interest", _DECLARE, "egress", [f"{PREFIX}/{g}/**"]),
        ]
        subjects.append({"id": f"host-{h}", "cert_common_names": [h], "link_protocols": ["tls", "quic"]})
        policies.append(
            {"rules": [f"{h}-{r}" for r in ("publish", "declare", "receive", "interest")], "subjects": [f"host-{h}"]}
        )
    if tls.readers:
        rules += [
            _rule("readers-declare", _DECLARE, "ingress", [f"{PREFIX}/{g}/**"]),
            _rule("readers-receive", ["put"], "egress", [f"{PREFIX}/{g}/**"]),
            _rule("readers-ask", ["query"], "ingress", [info_key(ANY_GRAPH)]),
            _rule("readers-answer", ["reply"], "egress", [info_key(g)]),
        ]
        subjects.append({"id": "readers", "cert_common_names": sorted(tls.readers), "link_protocols": ["tls", "quic"]})
        policies.append(
            {"rules": [f"readers-{r}" for r in ("declare", "receive", "ask", "answer")], "subjects": ["readers"]}
        )
    if tls.operators:
        rules += [
            _rule("operators-ask", ["query"], "ingress", [info_key(ANY_GRAPH)]),
            _rule("operators-answer", ["reply"], "egress", [info_key(g)]),
        ]
        subjects.append(
            {"id": "operators", "cert_common_names": sorted(tls.operators), "link_protocols": ["tls", "quic"]}
        )
        policies.append({"rules": ["operators-ask", "operators-answer"], "subjects": ["operators"]})
    for name in sorted(set(hosts) | set(tls.readers) | set(tls.operators)):  # parameter requests under one's name
        own = [param_request_key(g, name, "*")]
        rules += [
            _rule(f"params-{name}-ask", ["query"], "ingress", own),
            _rule(f"params-{name}-answer", ["reply"], "egress", own),
        ]
        subjects.append({"id": f"params-{name}", "cert_common_names": [name], "link_protocols": ["tls", "quic"]})
        policies.append({"rules": [f"params-{name}-ask", f"params-{name}-answer"], "subjects": [f"params-{name}"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects, "policies": policies}
