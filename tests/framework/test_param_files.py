"""``handflow param dump`` / ``param load`` (docs/tuning.md, "Parameter files"): the file format, whatever the
file holds, and both commands on a running configs/basic_chain.yaml."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from handflow.framework.commands.param_files import ParamFileError, dump, dump_text, read_param_file, same_value
from handflow.framework.runtime.discovery import live_runs

REPO = Path(__file__).resolve().parents[2]

names = st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), min_size=1, max_size=8)
values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False, allow_infinity=False) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(names, inner, max_size=3),
    max_leaves=6,
)
files = st.dictionaries(names, st.dictionaries(names, values, max_size=4), min_size=1, max_size=4)


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=200) | st.binary(max_size=200).map(lambda b: b.decode("latin-1")))
def test_any_text_reads_as_a_parameter_file_or_a_clear_error(text):
    try:
        data = read_param_file(text, "p.yaml")
    except ParamFileError as exc:
        assert str(exc).startswith("p.yaml:") and "Traceback" not in str(exc)
        return
    assert data and all(isinstance(n, str) and isinstance(p, dict) for n, p in data.items())
    json.dumps(data)  # what a request carries


@settings(max_examples=100, deadline=None)
@given(files)
def test_a_dump_reads_back_as_the_values_it_holds(params):
    replies = [{"node": node, "params": p} for node, p in params.items()]
    back = read_param_file(dump_text("g", replies))
    assert back.keys() == params.keys()
    assert all(same_value(back[n][k], v) for n, p in params.items() for k, v in p.items())


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("scale: {gain: [\n", "p.yaml:2: YAML syntax error"),
        ("- scale\n", "p.yaml:1: a parameter file maps node ids"),
        ("scale: 3\n", "p.yaml:1: node 'scale' needs a mapping"),
        ("scale:\n  gain: 2\nsink:\n  when: 2024-01-01\n", "p.yaml:4: sink.when: datetime.date(2024, 1, 1) is not"),
        ("scale: {gain: .nan}\n", "p.yaml:1: scale.gain: nan is not a plain value"),
        ("? [a, b]\n: {gain: 1}\n", "p.yaml:1: "),
        ("1: {gain: 1}\n", "node id 1 is not a name"),
    ],
)
def test_malformed_files_are_refused_with_file_line_and_what_to_change(text, says):
    with pytest.raises(ParamFileError, match=None) as info:
        read_param_file(text, "p.yaml")
    assert says in str(info.value)


def test_equal_values_are_equal_as_parameters():
    assert same_value(2, 2.0) and same_value([1, {"a": 2}], [1.0, {"a": 2.0}]) and same_value(None, None)
    assert not same_value(True, 1) and not same_value("2", 2) and not same_value([1], [1, 2])


def test_a_dump_missing_a_node_says_which_and_exits_1(tmp_path, capsys):
    """The replies as the parameter service gives them when node 'sink' is down."""
    replies = [{"ok": True, "node": "scale", "params": {"gain": 2.0}, "live": ["gain"], "plugin": "basic.transform"}]
    code = dump("g", ["scale", "sink"], lambda node, request, timeout: replies, str(tmp_path / "p.yaml"), 1.0)
    assert code == 1 and "node(s) sink did not answer" in capsys.readouterr().err
    assert read_param_file((tmp_path / "p.yaml").read_text()) == {"scale": {"gain": 2.0}}


# ----------------------------------------------------------------------------------------------
# a running graph
# ----------------------------------------------------------------------------------------------
def handflow(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", *args], cwd=cwd, capture_output=True, text=True, timeout=120
    )


@pytest.fixture
def chain(tmp_path, monkeypatch):
    """configs/basic_chain.yaml running (its log in the returned function)."""
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    log = (tmp_path / "run.log").open("w+")
    run = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(REPO / "configs/basic_chain.yaml")],
        cwd=tmp_path,
        env=dict(os.environ),
        stderr=log,
        text=True,
    )
    deadline = time.monotonic() + 60
    while not live_runs() or handflow("param", "get", "sink", cwd=tmp_path).returncode:
        assert time.monotonic() < deadline and run.poll() is None, "the graph did not start"
        time.sleep(0.2)
    yield lambda: (tmp_path / "run.log").read_text()
    run.terminate()
    run.wait(timeout=60)
    log.close()


@pytest.mark.slow
def test_dump_then_load_restores_the_graphs_parameters(chain, tmp_path):
    dumped = handflow("param", "dump", cwd=tmp_path)
    assert dumped.returncode == 0, dumped.stderr
    assert yaml.safe_load(dumped.stdout)["scale"] == {"gain": 2.0, "offset": 0.5}
    assert handflow("param", "dump", "--graph", "basic_chain", "p.yaml", cwd=tmp_path).returncode == 0
    assert (tmp_path / "p.yaml").read_text() == dumped.stdout

    assert handflow("param", "set", "scale.gain", "3", cwd=tmp_path).returncode == 0
    loaded = handflow("param", "load", "p.yaml", cwd=tmp_path)
    assert loaded.returncode == 0, loaded.stderr
    assert loaded.stdout.splitlines() == ["scale.gain = 2"]  # only what differs is sent
    assert handflow("param", "get", "scale.gain", cwd=tmp_path).stdout.strip() == "2"

    # start-only keys: refused, each named, unless --restart (one restart per node)
    (tmp_path / "p.yaml").write_text(
        dumped.stdout.replace("rate_hz: 50.0", "rate_hz: 25").replace("width: 3", "width: 4")
    )
    refused = handflow("param", "load", "p.yaml", cwd=tmp_path)
    assert refused.returncode == 1
    assert "source.rate_hz needs a restart" in refused.stderr and "source.width needs a restart" in refused.stderr
    restarted = handflow("param", "load", "--restart", "p.yaml", cwd=tmp_path)
    assert restarted.returncode == 0, restarted.stderr
    assert restarted.stdout.splitlines() == ["source.rate_hz = 25  (restarted)", "source.width = 4  (restarted)"]
    assert chain().count("started source (pid") == 2  # once more, for both keys
    assert handflow("param", "get", "source.width", cwd=tmp_path).stdout.strip() == "4"

    (tmp_path / "bad.yaml").write_text("scale: {gain: 5, gian: 2}\n")
    unknown = handflow("param", "load", "bad.yaml", cwd=tmp_path)
    assert unknown.returncode == 2 and "node 'scale' has no parameter 'gian'" in unknown.stderr
    assert "nothing changed" in unknown.stderr
    assert handflow("param", "get", "scale.gain", cwd=tmp_path).stdout.strip() == "2"
    assert handflow("param", "load", "p.yaml", "--graph", "nosuchgraph", cwd=tmp_path).returncode == 2
