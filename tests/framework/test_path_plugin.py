"""A plugin given by path in the graph, ``plugin: ./my_plugin.py:MyNode`` (docs/pipelines.md, "A plugin given by
path"): validated with clear errors, watched, recorded as written, replayed in lock-step like an installed one."""

from __future__ import annotations

import json
import signal
import subprocess
import sys

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from handflow.framework.files.mcap_reader import ReadReport, iter_recording
from handflow.framework.graphs.model import GraphError, load_graph
from handflow.framework.registry import load_plugin
from handflow.framework.runtime.plugin_sources import forget, plugin_files
from tests.framework._rec_helpers import handflow, unique, wait_until, write_graph
from tests.framework.test_watch import PLUGIN as WATCHED

PLUGIN = WATCHED.replace("SHIFT = 0.0", "SHIFT = 1.0") + "\n\nNotANode = dict\n"  # and a class that is no Node
NODES = """nodes:
  - id: source
    plugin: basic.signal
    params: {{kind: noise, rate_hz: 100, width: 3, seed: 1}}
  - id: shift
    plugin: {plugin}
    params: {{scale: 2.0}}
    inputs: {{in: source/out}}
  - id: sink
    plugin: basic.sink
    inputs: {{in: shift/out}}
"""
REPLAY = """external: {source/out: Array}
nodes:
  - id: shift
    plugin: ../plugins/shift.py:Shift
    params: {scale: 2.0}
    inputs: {in: source/out}
  - id: sink
    plugin: basic.sink
    inputs: {in: shift/out}
"""


def graph_with(tmp_path, plugin: str, name: str = "pathplug"):
    return write_graph(tmp_path / "graphs" / "g.yaml", name, NODES.format(plugin=plugin))


@pytest.fixture
def folder(tmp_path):
    (tmp_path / "graphs").mkdir()
    (tmp_path / "plugins").mkdir()
    (tmp_path / "plugins" / "shift.py").write_text(PLUGIN)
    return tmp_path


def test_a_path_plugin_loads_relative_to_the_graph_and_is_one_watched_file(folder):
    graph = load_graph(graph_with(folder, "../plugins/shift.py:Shift"))
    cls = graph.nodes["shift"].cls
    assert cls.__name__ == "Shift" and graph.nodes["shift"].params.scale == 2.0
    assert graph.nodes["shift"].spec.plugin == "../plugins/shift.py:Shift"  # as written
    source = (folder / "plugins" / "shift.py").resolve()
    assert plugin_files(cls) == {source}  # what --watch watches
    assert load_plugin(str(source) + ":Shift") is cls  # absolute: the same module, imported once
    source.write_text(PLUGIN.replace("SHIFT = 1.0", "SHIFT = 5.0"))
    forget({source})  # as a process forked after an edit does
    assert sys.modules[load_plugin("../plugins/shift.py:Shift", folder / "graphs").__module__].SHIFT == 5.0


@pytest.mark.parametrize(
    ("plugin", "says"),
    [
        ("./nothing.py:Shift", "no file {folder}/graphs/nothing.py (a path is relative to the graph file's folder"),
        ("../plugins/shift.py:Shfit", "plugins/shift.py:1 defines no 'Shfit' (its Node classes: Shift)"),
        ("../plugins/shift.py:NotANode", "'NotANode' (at "),
        ("../plugins/shift.py", "a plugin given by path is written FILE.py:ClassName"),
        ("../plugins/broken.py:Shift", "failed to load: SyntaxError"),
    ],
)
def test_a_path_plugin_that_does_not_load_is_refused_at_its_graph_line(folder, plugin, says):
    (folder / "plugins" / "broken.py").write_text(PLUGIN.replace("SHIFT = 1.0", "SHIFT = (1.0"))
    with pytest.raises(GraphError) as info:
        load_graph(graph_with(folder, plugin))
    text = str(info.value)
    assert f"g.yaml:7: plugin '{plugin}'" in text, text
    assert says.format(folder=folder) in text, text
    if "NotANode" in plugin:
        assert "is not a handflow.framework.plugin.Node subclass" in text
    if "broken" in plugin:
        assert f"(at {folder / 'plugins' / 'broken.py'}:5)" in text


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    name=st.tuples(
        st.sampled_from(["./", "../", "/", "../plugins/"]),
        st.text(max_size=20) | st.sampled_from(["shift", "broken", "nothing", "", "../graphs/g"]),
        st.sampled_from([".py:Shift", ".py:NotANode", ".py:", ".py", ":Shift", ".yaml:Shift", ""]),
    ).map("".join)
)
def test_any_plugin_path_validates_or_is_a_problem_at_its_line(folder, name):
    (folder / "plugins" / "broken.py").write_text(PLUGIN.replace("SHIFT = 1.0", "SHIFT = (1.0"))
    try:
        load_graph(graph_with(folder, json.dumps(name)))
    except GraphError as exc:
        assert "g.yaml:" in str(exc)


def test_plugins_shows_a_path_plugin_relative_to_the_current_folder(folder, monkeypatch, capsys):
    from handflow.framework import cli

    monkeypatch.chdir(folder)
    assert cli.main(["plugins", "./plugins/shift.py:Shift"]) == 0
    out = capsys.readouterr().out
    assert f"({folder / 'plugins' / 'shift.py'})" in out and "outputs: out [handflow.Array]" in out
    assert cli.main(["plugins", "./plugins/shift.py:Shfit", "--json"]) == 2
    assert "defines no 'Shfit'" in json.loads(capsys.readouterr().out)[0]["error"]


@pytest.mark.slow
def test_a_graph_with_a_path_plugin_runs_records_and_replays_in_lockstep(folder, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(folder / "runs"))
    graph = graph_with(folder, "../plugins/shift.py:Shift", unique("pathplug"))
    assert handflow("validate", str(graph), cwd=folder).returncode == 0
    live = handflow("run", str(graph), "--duration", "1.5", "--record", "live.mcap", cwd=folder)
    assert live.returncode == 0, live.stderr
    report = ReadReport(folder / "live.mcap")
    outputs = [rm.decode() for rm in iter_recording(folder / "live.mcap", ["shift/out"], report=report)]
    assert len(outputs) > 50
    assert report.metadata["handflow.plugins"]["shift"] == "../plugins/shift.py:Shift"
    attached = report.metadata["handflow.files"]["shift.plugin"]  # its source, as it ran
    assert attached.endswith("plugins/shift.py") and report.attachments[attached].data == PLUGIN.encode()

    target = write_graph(folder / "graphs" / "replay.yaml", unique("pathreplay"), REPLAY)
    replay = handflow(
        "replay", "live.mcap", "--into", str(target), "--lockstep", "--record", "replayed.mcap", cwd=folder
    )
    assert replay.returncode == 0, replay.stderr
    same = handflow("compare", "live.mcap", "replayed.mcap", cwd=folder)
    assert same.returncode == 0 and "equal: 2 topic(s)" in same.stdout, same.stdout + same.stderr


@pytest.mark.slow
def test_watch_restarts_the_nodes_of_a_path_plugin_when_its_file_changes(folder, monkeypatch):
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(folder / "runs"))
    graph = graph_with(folder, "../plugins/shift.py:Shift", unique("pathwatch"))
    log = (folder / "run.log").open("w+")
    argv = [sys.executable, "-m", "handflow.framework.cli", "run", str(graph), "--watch"]
    run = subprocess.Popen(argv, cwd=folder, stderr=log, text=True)

    def shifted() -> bool:
        echoed = handflow("echo", "shift/out", "--once", "--json", cwd=folder)
        return echoed.returncode == 0 and min(json.loads(echoed.stdout)["data"]) > 50

    try:
        wait_until(lambda: handflow("param", "get", "shift", cwd=folder).returncode == 0, 60, "the graph")
        assert not shifted()
        (folder / "plugins" / "shift.py").write_text(PLUGIN.replace("SHIFT = 1.0", "SHIFT = 100.0"))
        wait_until(shifted, 30, "the edited plugin's output")
        wait_until(lambda: "reloaded: restarted shift (" in (folder / "run.log").read_text(), 10, "no 'reloaded'")
    finally:
        run.send_signal(signal.SIGINT)
        run.wait(timeout=60)
        log.close()
    output = (folder / "run.log").read_text()
    assert "shift.py changed) in" in output and output.count("started source (pid") == 1
