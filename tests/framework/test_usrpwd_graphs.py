"""Zenoh user/password authentication of graphs and tools (docs/security.md).

A real launcher with ``zenoh.usrpwd``; real ``handflow record`` processes and a real Zenoh peer
play the rightful tool, the wrong password and the anonymous intruder.
"""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path

import pytest
import zenoh
from hypothesis import given, settings
from hypothesis import strategies as st

from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.graphs.model import validate_file
from handflow.framework.runtime.discovery import DiscoveryError, join, live_runs, write_run_file
from handflow.framework.security.credentials import CredentialsError, parse_credentials, read_credentials

from .test_runtime_e2e import chain_graph, read_sink, start

LOGINS = "# the lab's logins\nlab:s3cret-lab\n\nviewer:look:only\n"


def _graph(tmp_path: Path, usrpwd: str = "{credentials: site.credentials, user: lab}", extra: str = "") -> Path:
    (tmp_path / "site.credentials").write_text(LOGINS)
    return chain_graph(tmp_path, zenoh=f"zenoh: {{usrpwd: {usrpwd}{extra}}}")


def _problems(path: Path) -> list[str]:
    return [f"{p.line}: {p.message}" for p in validate_file(path)[1]]


def test_credentials_file_format():
    assert parse_credentials(LOGINS) == {"lab": "s3cret-lab", "viewer": "look:only"}
    for text, message in [
        ("", "no credentials"),
        ("lab\n", "expected one 'user:password' per line"),
        ("la b:x\n", "expected one 'user:password' per line"),
        ("lab:\n", "must be non-empty"),
        ("lab:a\nlab:b\n", "appears twice"),
        ("lab:pass\x07word", "must be non-empty printable"),
    ]:
        with pytest.raises(CredentialsError, match=message):
            parse_credentials(text, "f")
    with pytest.raises(CredentialsError, match=r"f:2: user 'lab' appears twice"):
        parse_credentials("lab:a\nlab:b\n", "f")


def test_a_login_names_its_user_and_never_prints_passwords(tmp_path):
    (tmp_path / "c").write_text(LOGINS)
    creds = read_credentials(tmp_path / "c")
    assert creds.login("viewer") == ("viewer", "look:only")
    with pytest.raises(CredentialsError, match="several users .*pass --user NAME"):
        creds.login(None)
    with pytest.raises(CredentialsError, match="no user 'eve'; add a line 'eve:PASSWORD'"):
        creds.login("eve")
    assert "s3cret" not in repr(creds) and "look" not in repr(creds)
    with pytest.raises(CredentialsError, match="does not exist; create it"):
        read_credentials(tmp_path / "missing")
    (tmp_path / "bin").write_bytes(b"\xff\xfe:\x00")
    with pytest.raises(CredentialsError, match="not UTF-8"):
        read_credentials(tmp_path / "bin")


_LINES = st.lists(
    st.one_of(
        st.text(max_size=30),
        st.builds(lambda u, p: f"{u}:{p}", st.from_regex(r"[A-Za-z0-9_]{1,8}", fullmatch=True), st.text(max_size=12)),
        st.sampled_from(["#", "", ":", "lab:", ":pw", " lab:pw ", "a:b:c", "\x00", "é:ü"]),
    ),
    max_size=8,
)


@settings(max_examples=200, deadline=None)
@given(_LINES)
def test_mutated_credentials_parse_or_fail_clearly(lines):
    text = "\n".join(lines)
    try:
        users = parse_credentials(text, "site.credentials")
    except CredentialsError as exc:
        assert str(exc).startswith("site.credentials")
        return
    assert users and all(p and p == p.strip() for p in users.values())
    assert parse_credentials("\n".join(f"{u}:{p}" for u, p in users.items())) == users  # what the hub is given


_SETTING = st.one_of(st.text(max_size=20), st.integers(), st.none(), st.lists(st.text(max_size=5), max_size=2))


@settings(max_examples=150, deadline=None)
@given(credentials=_SETTING, user=_SETTING, contents=st.binary(max_size=40))
def test_mutated_usrpwd_settings_validate_or_fail_with_a_line(tmp_path_factory, credentials, user, contents):
    d = tmp_path_factory.mktemp("fuzz")
    (d / "site.credentials").write_bytes(contents)
    settings_yaml = json.dumps({"credentials": credentials, "user": user})  # JSON is YAML
    path = d / "graph.yaml"
    path.write_text(f"name: fuzz\nzenoh: {{usrpwd: {settings_yaml}}}\nnodes: []\n")
    graph, problems = validate_file(path)
    assert (graph is None) == bool(problems)
    assert all(p.line >= 1 and p.message for p in problems)


def test_validate_explains_a_missing_malformed_or_mismatched_credentials_file(tmp_path):
    path = _graph(tmp_path, "{credentials: nowhere.credentials}")
    assert _problems(path) == [
        f"2: zenoh.usrpwd.credentials: credentials file {tmp_path / 'nowhere.credentials'} does not exist; "
        "create it with one 'user:password' per line (user: letters, digits, '_', '-', '.', '@'; '#' starts a comment line)"
    ]
    proc = start("validate", str(path))
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and f"{path}:2: zenoh.usrpwd.credentials" in err and "Traceback" not in err
    (tmp_path / "nowhere.credentials").write_text("lab:ok\nbroken line\n")
    assert "nowhere.credentials:2: expected one 'user:password'" in _problems(path)[0]
    path = _graph(tmp_path, "{credentials: site.credentials, user: eve}")
    assert "has no user 'eve'" in _problems(path)[0]
    assert _problems(_graph(tmp_path)) == []


def test_run_says_which_login_to_choose_when_the_file_holds_several(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    proc = start("run", str(_graph(tmp_path, "{credentials: site.credentials}")), "--duration", "1")
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and "holds several users (lab, viewer); pass `handflow run --host NAME`" in err


def test_passwords_over_plain_tcp_beyond_loopback_need_insecure(tmp_path):
    path = _graph(tmp_path, extra=", listen: [tcp/0.0.0.0:7450]")
    (problem,) = _problems(path)
    assert "passwords of 'usrpwd' travel in clear text" in problem and "insecure: true" in problem
    path.write_text(path.read_text().replace("listen:", "insecure: true, listen:"))
    assert _problems(path) == []


def test_a_tool_without_credentials_for_a_usrpwd_graph_is_told_what_to_pass(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path))
    write_run_file("g", "tcp/127.0.0.1:9", "g.yaml", usrpwd=True)
    with pytest.raises(DiscoveryError, match="asks for a user and password: pass --credentials FILE"):
        join("g")
    with pytest.raises(DiscoveryError, match="--user needs --credentials"):
        join("g", user="lab")


def test_a_credentials_file_others_can_read_is_reported(tmp_path, caplog):
    path = tmp_path / "c"
    path.write_text(LOGINS)
    path.chmod(0o600)
    read_credentials(path, warn_shared=True)
    assert "chmod 600" not in caplog.text
    path.chmod(0o644)
    read_credentials(path)
    assert "chmod 600" not in caplog.text  # validation and node processes stay quiet
    read_credentials(path, warn_shared=True)
    assert f"readable by other users; restrict it with `chmod 600 {path}`" in caplog.text


def _recorded(path: Path) -> list[str]:
    return [rm.topic for rm in iter_recording(path)] if path.exists() else []


@pytest.mark.slow
def test_a_usrpwd_graph_runs_records_and_admits_only_tools_with_the_right_password(tmp_path, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    graph = _graph(tmp_path)
    graph.write_text(graph.read_text() + f"record: {{path: {tmp_path / 'run.mcap'}}}\n")
    (tmp_path / "viewer.credentials").write_text("viewer:look:only\n")
    (tmp_path / "wrong.credentials").write_text("viewer:guess\n")
    run = start("run", str(graph), "--duration", "60")
    try:
        deadline = time.time() + 20
        while time.time() < deadline and not live_runs():
            time.sleep(0.2)
        assert live_runs(), "the launcher did not start"
        info = live_runs()[0]
        assert info.usrpwd
        anonymous = zenoh.Config()  # a peer without credentials, straight at the hub
        anonymous.insert_json5("mode", '"peer"')
        anonymous.insert_json5("scouting/multicast/enabled", "false")
        anonymous.insert_json5("connect/endpoints", json.dumps([info.hub]))
        intruder = zenoh.open(anonymous)
        stolen: list[bytes] = []
        intruder.declare_subscriber(f"handflow/{info.graph}/**", lambda s: stolen.append(s.payload.to_bytes()))
        tools = {
            label: start("record", info.graph, "--duration", "3", "--out", str(tmp_path / f"{label}.mcap"), *args)
            for label, args in (
                ("viewer", ("--credentials", str(tmp_path / "viewer.credentials"))),
                ("wrong", ("--credentials", str(tmp_path / "wrong.credentials"))),
                ("none", ()),
            )
        }
        outputs = {label: p.communicate(timeout=60) for label, p in tools.items()}
        monitor = start("monitor", "--once", "--json", "--credentials", str(tmp_path / "viewer.credentials"))
        watched, _ = monitor.communicate(timeout=60)
        for _ in range(20):
            intruder.put(f"handflow/{info.graph}/source/out", b"FORGED")
        time.sleep(0.5)
        run.send_signal(signal.SIGINT)
        _, err = run.communicate(timeout=60)
        intruder.close()
    finally:
        if run.poll() is None:
            run.kill()
    assert run.returncode == 0, err
    assert len(read_sink(tmp_path / "sink.jsonl")) > 100  # the nodes logged in to their own hub
    assert _recorded(tmp_path / "run.mcap").count(f"handflow/{info.graph}/scale/out") > 100
    assert tools["viewer"].returncode == 0, outputs["viewer"]
    assert monitor.returncode == 0 and {n["id"] for n in json.loads(watched)["nodes"]} == {"source", "scale", "sink"}
    assert _recorded(tmp_path / "viewer.mcap").count(f"handflow/{info.graph}/source/out") > 100  # 3 s at 100 Hz
    assert tools["wrong"].returncode == 2 and "could not join" in outputs["wrong"][1]
    assert "with user 'viewer'" in outputs["wrong"][1] and "guess" not in outputs["wrong"][1]
    assert tools["none"].returncode == 2 and "pass --credentials FILE" in outputs["none"][1]
    assert not (tmp_path / "wrong.mcap").exists() or _recorded(tmp_path / "wrong.mcap") == []
    assert set(stolen) <= {b"FORGED"}  # nothing of the graph, at most its own puts echoed locally
    assert "look:only" not in err and "s3cret" not in err  # no password in the launcher's log


@pytest.mark.slow
def test_over_tls_a_tool_needs_both_its_certificate_and_its_password(tmp_path, monkeypatch):
    pytest.importorskip("cryptography")
    from handflow.framework.network.sessions import free_tcp_port
    from handflow.framework.security import certs

    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    ca = tmp_path / "certs"
    certs.init_ca(ca)
    for host in ("a", "viewer"):
        certs.add_host(ca, host)
    tls_ep = f"tls/127.0.0.1:{free_tcp_port()}"
    graph = _graph(tmp_path, extra=f", listen: [{tls_ep}], tls: {{certs: {ca}, host: a, readers: [viewer]}}")
    (tmp_path / "viewer.credentials").write_text("viewer:look:only\n")
    (tmp_path / "wrong.credentials").write_text("viewer:guess\n")
    run = start("run", str(graph), "--duration", "60")
    try:
        deadline = time.time() + 20
        while time.time() < deadline and not live_runs():
            time.sleep(0.2)
        assert live_runs(), "the launcher did not start"
        name = live_runs()[0].graph
        tls = ("--connect", tls_ep, "--certs", str(ca), "--cert-name", "viewer")
        tools = {
            label: start("record", name, "--duration", "3", "--out", str(tmp_path / f"{label}.mcap"), *tls, *args)
            for label, args in (
                ("both", ("--credentials", str(tmp_path / "viewer.credentials"))),
                ("wrong", ("--credentials", str(tmp_path / "wrong.credentials"))),
                ("certificate-only", ()),
            )
        }
        outputs = {label: p.communicate(timeout=60) for label, p in tools.items()}
        run.send_signal(signal.SIGINT)
        _, err = run.communicate(timeout=60)
    finally:
        if run.poll() is None:
            run.kill()
    assert run.returncode == 0, err
    assert tools["both"].returncode == 0, outputs["both"]
    assert _recorded(tmp_path / "both.mcap").count(f"handflow/{name}/source/out") > 100  # 3 s at 100 Hz over TLS
    assert tools["wrong"].returncode == 2
    assert "with certificate 'viewer' and user 'viewer'" in outputs["wrong"][1]
    assert tools["certificate-only"].returncode == 2 and "could not join" in outputs["certificate-only"][1]


@pytest.mark.slow
def test_two_graphs_log_in_to_each_other_and_a_wrong_password_joins_nothing(tmp_path, monkeypatch):
    from handflow.framework.network.sessions import free_tcp_port

    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    template = chain_graph(
        tmp_path, zenoh="zenoh: {usrpwd: {credentials: site.credentials}, ZENOH}", hosts=("a", "b", "b")
    )
    sides = {"a": ("listen", "a:alpha\nb:beta\n"), "b": ("connect", "a:alpha\nb:beta\n"), "c": ("connect", "b:wrong\n")}
    runs = {}
    try:
        for side, (key, logins) in sides.items():
            d = tmp_path / side
            d.mkdir()
            (d / "site.credentials").write_text(logins)
            graph = (
                template.read_text()
                .replace("ZENOH", f"{key}: [{endpoint}]")
                .replace(str(tmp_path / "sink"), str(d / "sink"))
            )
            (d / "graph.yaml").write_text(graph)
            runs[side] = start("run", str(d / "graph.yaml"), "--host", "a" if side == "a" else "b", "--duration", "60")
            if side == "a":
                deadline = time.time() + 20
                while time.time() < deadline and not live_runs():
                    time.sleep(0.2)
        deadline = time.time() + 30
        while time.time() < deadline and len(read_sink(tmp_path / "b" / "sink.jsonl")) < 100:
            time.sleep(0.2)
        time.sleep(1)
        for p in runs.values():
            p.send_signal(signal.SIGINT)
        errors = {side: p.communicate(timeout=60)[1] for side, p in runs.items()}
    finally:
        for p in runs.values():
            if p.poll() is None:
                p.kill()
    assert all(p.returncode == 0 for p in runs.values()), errors
    assert len(read_sink(tmp_path / "b" / "sink.jsonl")) >= 100  # a's source reached b's nodes
    assert read_sink(tmp_path / "c" / "sink.jsonl") == []  # c's hub never got in
