"""Live parameters of a TLS graph (docs/security.md, docs/tuning.md): readers may read them, only hosts and
``zenoh.tls.operators`` may change them; a refused change exits 2 and the hub logs it.  Real launcher, real
certificates, `handflow param` over mutual TLS."""

from __future__ import annotations

import signal
import time

import pytest

pytest.importorskip("cryptography")

from handflow.framework.network.sessions import free_tcp_port
from handflow.framework.runtime.discovery import live_runs
from handflow.framework.security import certs

from .test_runtime_e2e import chain_graph, start

pytestmark = pytest.mark.slow


def _param(*args: str, tls: tuple[str, str, str] | None = None) -> tuple[int, str, str]:
    extra = ["--connect", tls[0], "--certs", tls[1], "--cert-name", tls[2]] if tls else []
    proc = start("param", *args, *extra)
    out, err = proc.communicate(timeout=60)
    return proc.returncode, out.strip(), err


def test_readers_read_operators_and_hosts_set_and_a_refused_set_is_logged(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    ca = tmp_path / "certs"
    certs.init_ca(ca)
    for host in ("a", "viewer", "laptop", "mallory"):
        certs.add_host(ca, host)
    tls_ep = f"tls/127.0.0.1:{free_tcp_port()}"
    zenoh = f"zenoh: {{listen: [{tls_ep}], tls: {{certs: {ca}, readers: [viewer], operators: [laptop]}}}}"
    graph = chain_graph(tmp_path, zenoh=zenoh, hosts=("a", "a", "a"))
    run = start("run", str(graph), "--host", "a", "--duration", "60")
    try:
        deadline = time.time() + 30
        while time.time() < deadline and not live_runs():
            time.sleep(0.2)
        assert live_runs(), "the launcher did not start"
        ca_dir = str(ca)
        while time.time() < deadline and _param("get", "scale.gain", tls=(tls_ep, ca_dir, "viewer"))[0] != 0:
            time.sleep(0.5)  # the nodes are up
        read = _param("get", "scale.gain", tls=(tls_ep, ca_dir, "viewer"))
        reader_set = _param("set", "scale.gain", "5", tls=(tls_ep, ca_dir, "viewer"))
        operator_set = _param("set", "scale.gain", "4", tls=(tls_ep, ca_dir, "laptop"))
        stranger_set = _param("set", "scale.gain", "6", tls=(tls_ep, ca_dir, "mallory"))
        host_set = _param("set", "scale.offset", "0.25")  # on the host itself (its hub's loopback link)
        after = _param("list", "scale", tls=(tls_ep, ca_dir, "viewer"))
        run.send_signal(signal.SIGINT)
        _, hub_log = run.communicate(timeout=60)
    finally:
        if run.poll() is None:
            run.kill()
    assert read[:2] == (0, "2"), read
    assert reader_set[0] == 2 and "certificate 'viewer' may not change parameters" in reader_set[2]
    assert "zenoh.tls.operators" in reader_set[2]
    assert "refused: 'viewer' may not set scale.gain" in hub_log  # the hub logs the refusal
    assert operator_set[:2] == (0, "scale.gain = 4  (live)"), operator_set
    assert stranger_set[0] == 2 and "zenoh.tls.readers" in stranger_set[2]  # not even admitted to the graph
    assert host_set[0] == 0, host_set
    assert after[1].splitlines() == ["scale.gain = 4  (live)", "scale.offset = 0.25  (live)"], after
