"""Multi-host graphs over mutual TLS with access control derived from the graph (docs/security.md).

Two real launchers on this machine, each with its own certificate, share one graph over a TLS
endpoint on 127.0.0.1; real Zenoh sessions play the intruders.
"""

from __future__ import annotations

import datetime as dt
import json
import signal
import time
from pathlib import Path

import pytest

pytest.importorskip("cryptography")

import zenoh

from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.files.mcap_writer import McapWriter
from handflow.framework.graphs.model import load_graph, validate_file
from handflow.framework.messages import Array, Header
from handflow.framework.network.sessions import free_tcp_port
from handflow.framework.runtime.discovery import join, live_runs
from handflow.framework.security import certs
from handflow.framework.security.access import access_control

from ._rec_helpers import wait_until
from .test_runtime_e2e import chain_graph, read_sink, start


@pytest.fixture
def ca(tmp_path) -> Path:
    d = tmp_path / "certs"
    certs.init_ca(d)
    for host in ("a", "b", "mallory"):
        certs.add_host(d, host)
    return d


def _graph(tmp_path: Path, zenoh_yaml: str, hosts=("a", "b", "b")) -> Path:
    return chain_graph(tmp_path, zenoh=zenoh_yaml, hosts=hosts)


def _problems(path: Path) -> str:
    return " ".join(p.message for p in validate_file(path)[1])


def test_listening_beyond_loopback_without_tls_is_refused_unless_insecure(tmp_path):
    path = _graph(tmp_path, "zenoh: {listen: [tcp/0.0.0.0:7450]}")
    assert "without TLS" in _problems(path) and "insecure: true" in _problems(path)
    path.write_text(
        path.read_text().replace("listen: [tcp/0.0.0.0:7450]", "listen: [tcp/0.0.0.0:7450], insecure: true")
    )
    assert _problems(path) == ""
    path.write_text(
        path.read_text().replace("listen: [tcp/0.0.0.0:7450], insecure: true", "connect: [tls/10.0.0.2:7450]")
    )
    assert "needs certificates" in _problems(path)
    path.write_text(path.read_text().replace("connect: [tls/10.0.0.2:7450]", "listen: [tcp/127.0.0.1:7450]"))
    assert _problems(path) == ""  # loopback stays allowed


def test_validate_command_explains_the_refusal(tmp_path):
    path = _graph(tmp_path, "zenoh: {listen: [tcp/0.0.0.0:7450]}")
    proc = start("validate", str(path))
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2
    assert f"{path}:2:" in err and "any peer that reaches it could join" in err


def test_missing_expired_and_foreign_certificates_are_clear_errors(ca, tmp_path):
    with pytest.raises(certs.CertError, match="no certificate for host 'c'.*handflow certs add-host"):
        certs.check_host_files(ca, "c")
    certs.add_host(ca, "old", days=1, not_before=dt.datetime.now(dt.timezone.utc) - dt.timedelta(days=3))
    with pytest.raises(certs.CertError, match="expired"):
        certs.check_host_files(ca, "old")
    other = tmp_path / "other"
    certs.init_ca(other)
    certs.add_host(other, "x")
    for suffix in ("pem", "key"):
        (ca / f"x.{suffix}").write_bytes((other / f"x.{suffix}").read_bytes())
    with pytest.raises(certs.CertError, match="not signed by the CA"):
        certs.check_host_files(ca, "x")
    with pytest.raises(certs.CertError, match="already exists"):
        certs.init_ca(ca)


def test_access_control_follows_the_graph(ca, tmp_path):
    port = free_tcp_port()
    z = f"zenoh: {{listen: [tls/127.0.0.1:{port}], tls: {{certs: {ca}, readers: [laptop]}}}}"
    acl = access_control(load_graph(_graph(tmp_path, z)), "a")
    rules = {r["id"]: r for r in acl["rules"]}
    name = load_graph(_graph(tmp_path, z)).name
    assert rules["b-publish"]["key_exprs"] == [
        f"handflow/{name}/_runtime/events",
        f"handflow/{name}/scale/**",
        f"handflow/{name}/sink/**",
    ]
    assert rules["b-receive"]["key_exprs"] == [f"handflow/{name}/**"]  # b's hub relays to the readers joined to it
    assert "readers-publish" not in rules and rules["readers-receive"]["key_exprs"] == [f"handflow/{name}/**"]
    assert rules["readers-ask"]["key_exprs"] == ["handflow/*/_runtime/info"]  # which graphs the hub serves
    assert acl["default_permission"] == "deny"
    no_readers = access_control(load_graph(_graph(tmp_path, z.replace(", readers: [laptop]", ""))), "a")
    rules = {r["id"]: r for r in no_readers["rules"]}
    assert f"handflow/{name}/source/out" in rules["b-receive"]["key_exprs"]  # only what b's nodes consume
    assert f"handflow/{name}/**" not in rules["b-receive"]["key_exprs"]
    assert not any(r.startswith("readers") for r in rules)


def _session(
    endpoint: str, ca_dir: Path | None, name: str | None, root: Path | None = None, mode: str = "peer"
) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    tls = {"root_ca_certificate": str(root or ca_dir / "ca.pem"), "verify_name_on_connect": False}
    if name:
        tls |= {  # presented only with mTLS on (without, every one of these sessions was refused alike)
            "connect_certificate": str(ca_dir / f"{name}.pem"),
            "connect_private_key": str(ca_dir / f"{name}.key"),
            "enable_mtls": True,
        }
    for key, value in tls.items():
        conf.insert_json5(f"transport/link/tls/{key}", json.dumps(value))
    return zenoh.open(conf)


@pytest.mark.slow
def test_two_graphs_over_mutual_tls_admit_only_rightful_peers(ca, tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    port = free_tcp_port()
    tls_ep = f"tls/127.0.0.1:{port}"
    graph = _graph(tmp_path, f"zenoh: {{listen: [{tls_ep}], tls: {{certs: {ca}}}}}")
    graph_b = tmp_path / "graph_b.yaml"
    graph_b.write_text(graph.read_text().replace(f"listen: [{tls_ep}]", f"connect: [{tls_ep}]"))
    name = load_graph(graph).name
    a = start("run", str(graph), "--host", "a")
    b = None
    sessions: list[zenoh.Session] = []
    try:
        deadline = time.time() + 20
        while time.time() < deadline and not live_runs():
            time.sleep(0.2)
        assert live_runs(), "launcher a did not start"
        hub = live_runs()[0].hub
        b = start("run", str(graph_b), "--host", "b")
        seen: list[tuple[str, bytes]] = []
        # a trusted process on machine A (loopback), a client of the hub like its node processes: a peer would
        # listen, and the peers that gossip finds on the hub (mallory's session) would link to it directly
        local = _session(hub, None, None, root=ca / "ca.pem", mode="client")
        sessions.append(local)
        local.declare_subscriber(f"handflow/{name}/**", lambda s: seen.append((str(s.key_expr), s.payload.to_bytes())))
        # intruders: no certificate, a certificate of another CA, a valid certificate of an unknown host,
        # and host b's valid certificate trying to publish a topic only host a's node owns
        other = tmp_path / "other"
        certs.init_ca(other)
        certs.add_host(other, "a")
        intruders = {
            "nocert": _session(tls_ep, ca, None),
            "foreign-ca": _session(tls_ep, other, "a"),
            "mallory": _session(tls_ep, ca, "mallory"),
            "b": _session(tls_ep, ca, "b"),
        }
        sessions += intruders.values()
        received: dict[str, list[bytes]] = {k: [] for k in intruders}
        for who, s in intruders.items():
            s.declare_subscriber(
                f"handflow/{name}/**", lambda smp, who=who: received[who].append(smp.payload.to_bytes())
            )
        # b's nodes are up and a's data reaches them over TLS, their heartbeats reach a, and the intruder with
        # b's valid certificate is linked to a (the others are refused by TLS)
        wait_until(lambda: len(read_sink(tmp_path / "sink.jsonl")) > 100, 60, "b's sink to handle 100 messages")
        wait_until(lambda: f"handflow/{name}/scale/_health" in {k for k, _ in seen}, 30, "b's heartbeats on a")
        linked = lambda s: list(s.info.routers_zid()) or list(s.info.peers_zid())  # noqa: E731
        wait_until(lambda: linked(intruders["b"]), 30, "the session with b's certificate to link to a")
        for _ in range(20):  # paced, over 2 s
            for who, s in intruders.items():
                s.put(f"handflow/{name}/source/out", b"FORGED " + who.encode())
                s.put(f"handflow/{name}/scale/out", b"FORGED " + who.encode())
            time.sleep(0.1)
        b.send_signal(signal.SIGINT)  # the trusted session goes on listening while both launchers stop
        _, err_b = b.communicate(timeout=60)
        a.send_signal(signal.SIGINT)
        _, err_a = a.communicate(timeout=60)
    finally:
        for session in sessions:  # an open session's threads would hold pytest at its exit
            session.close()
        for proc in (a, b):
            if proc is not None and proc.poll() is None:
                proc.kill()
    assert a.returncode == 0 and b.returncode == 0, err_a + err_b
    assert len(read_sink(tmp_path / "sink.jsonl")) > 100  # a's source reached b's nodes over TLS
    keys = {k for k, _ in seen}
    assert f"handflow/{name}/scale/_health" in keys  # b's runtime topics reach a through both access controls
    # ... but not outputs no node of a consumes (the session holding b's certificate may put its own there)
    assert not any(k == f"handflow/{name}/scale/out" and not p.startswith(b"FORGED") for k, p in seen)
    forged = {p for _, p in seen if p.startswith(b"FORGED")}
    assert forged <= {b"FORGED b"}, forged  # only b's own topic (scale/out) may come from b
    assert not any(k.endswith("/source/out") and p.startswith(b"FORGED") for k, p in seen)
    for who in ("nocert", "foreign-ca", "mallory"):  # their own puts echo locally; nothing of the graph arrives
        assert all(p.startswith(b"FORGED") for p in received[who]), who


def _recorded(path: Path) -> list[str]:
    return [rm.topic for rm in iter_recording(path)] if path.exists() else []


def _tool(command: str, target: str, endpoint: str, cert_dir: Path, who: str, *args: str):
    """``handflow record|replay`` joining over TLS with the certificate ``who`` of ``cert_dir``."""
    return start(command, target, *args, "--connect", endpoint, "--certs", str(cert_dir), "--cert-name", who)


@pytest.mark.slow
def test_tools_on_another_host_read_with_their_certificate_and_publish_only_when_granted(ca, tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    for host in ("viewer", "laptop"):
        certs.add_host(ca, host)
    other = tmp_path / "other"  # a certificate named like a reader, from another CA
    certs.init_ca(other)
    certs.add_host(other, "viewer")
    tls_ep = f"tls/127.0.0.1:{free_tcp_port()}"
    name = f"readers_{tmp_path.name[-8:].replace('-', '_')}"
    graph = tmp_path / "graph.yaml"
    graph.write_text(f"""name: {name}
external: {{glove/raw: Array}}
zenoh:
  listen: [{tls_ep}]
  tls: {{certs: {ca}, readers: [viewer, laptop], publishers: {{glove/raw: [laptop]}}}}
nodes:
  - {{id: source, plugin: basic.signal, host: a, params: {{kind: sine, rate_hz: 50, width: 3}}}}
  - {{id: sink, plugin: basic.sink, host: a, params: {{jsonl: {tmp_path / "sink.jsonl"}}}, inputs: {{in: glove/raw}}}}
""")
    take = tmp_path / "take.mcap"  # what the laptop replays: 40 frames of the external topic
    with McapWriter(take) as w:
        for i in range(40):
            msg = Array(data=[float(i), 0.0, 1.0])
            msg.header = Header("glove", i + 1, 1_700_000_000_000_000_000 + i * 10_000_000)
            w.write("handflow/field/glove/raw", msg, log_time_ns=msg.header.stamp_ns)
    a = start("run", str(graph), "--host", "a", "--duration", "60")
    sessions: list[zenoh.Session] = []
    try:
        deadline = time.time() + 20
        while time.time() < deadline and not live_runs():
            time.sleep(0.2)
        assert live_runs(), "launcher a did not start"
        seen: list[tuple[str, bytes]] = []
        local = join(None, live_runs()[0].hub)[0]  # a trusted process on machine A (loopback)
        sessions.append(local)
        local.declare_subscriber(f"handflow/{name}/**", lambda s: seen.append((str(s.key_expr), s.payload.to_bytes())))
        while time.time() < deadline + 20 and not any(k.endswith("/source/out") for k, _ in seen):
            time.sleep(0.2)  # the graph's nodes are up
        records = {
            label: _tool("record", name, tls_ep, d, who, "--duration", "3", "--out", str(tmp_path / f"{label}.mcap"))
            for label, d, who in (("viewer", ca, "viewer"), ("mallory", ca, "mallory"), ("foreign", other, "viewer"))
        }
        forgers = {who: join(None, tls_ep, str(ca), who)[0] for who in ("viewer", "laptop")}
        sessions += forgers.values()
        heard: dict[str, int] = dict.fromkeys(forgers, 0)  # the readers' sessions receive the graph: linked
        for who, forger in forgers.items():
            forger.declare_subscriber(
                f"handflow/{name}/source/out", lambda _s, who=who: heard.__setitem__(who, heard[who] + 1)
            )
        wait_until(lambda: all(heard.values()), timeout=30, what="the readers' sessions to be linked to a")
        for _ in range(20):
            for who, s in forgers.items():
                s.put(f"handflow/{name}/source/out", b"FORGED " + who.encode())
            forgers["viewer"].put(f"handflow/{name}/glove/raw", b"FORGED viewer")
            time.sleep(0.05)
        outputs = {label: p.communicate(timeout=60) for label, p in records.items()}
        replay = _tool("replay", str(take), tls_ep, ca, "laptop", "--graph", name)
        _, replay_err = replay.communicate(timeout=60)
        denied = _tool("replay", str(take), tls_ep, ca, "mallory", "--graph", name)
        _, denied_err = denied.communicate(timeout=60)
        a.send_signal(signal.SIGINT)
        _, err_a = a.communicate(timeout=60)
    finally:
        for session in sessions:
            session.close()
        if a.poll() is None:
            a.kill()
    assert a.returncode == 0, err_a
    assert records["viewer"].returncode == 0, outputs
    assert records["foreign"].returncode == 2 and "could not join" in outputs["foreign"][1]  # refused by TLS
    assert records["mallory"].returncode == 2 and "zenoh.tls.readers" in outputs["mallory"][1]  # refused by the ACL
    viewer = _recorded(tmp_path / "viewer.mcap")
    assert viewer.count(f"handflow/{name}/source/out") > 50, outputs["viewer"]  # 3 s at 50 Hz, read over TLS
    assert _recorded(tmp_path / "mallory.mcap") == [] and _recorded(tmp_path / "foreign.mcap") == []
    assert not [k for k, p in seen if p.startswith(b"FORGED")]  # readers publish nothing of the graph
    assert replay.returncode == 0, replay_err
    assert len(read_sink(tmp_path / "sink.jsonl")) == 40  # the granted replay reached the graph's node
    assert denied.returncode == 1 and "grant certificate 'mallory'" in denied_err
