"""`handflow run` says what it is doing while a graph starts (docs/pipelines.md, "Start-up"): a first line
before anything slow, a line per node as it becomes ready, then the ready line with the time since the
command.  The order is asserted here; how soon the first line comes is measured by benchmarks/startup.py."""

from __future__ import annotations

import os
import re

import pytest

pytestmark = pytest.mark.slow


def test_run_says_what_it_does_then_each_node_ready_then_all(tmp_path, run_handflow):
    graph = tmp_path / "g.yaml"
    graph.write_text(
        "name: startup_lines\nnodes:\n"
        "  - {id: source, plugin: basic.signal, params: {rate_hz: 20}}\n"
        "  - {id: scale, plugin: basic.transform, group: pair, inputs: {in: source/out}}\n"
        "  - {id: sink, plugin: basic.sink, group: pair, inputs: {in: scale/out}}\n"
    )
    proc = run_handflow(
        "run",
        str(graph),
        "--duration",
        "1",
        check=True,
        env={**os.environ, "HANDFLOW_RUN_DIR": str(tmp_path / "runs")},
        cwd=tmp_path,
    )
    lines = [re.sub(r"^\S+ \S+ \w+ \[[\w.]+\] ", "", line) for line in proc.stderr.splitlines()]
    assert lines[0] == f"handflow run {graph}: importing its plugins, checking its inputs, starting its processes"
    checked = next(
        i
        for i, line in enumerate(lines)
        if re.fullmatch(r"graph 'startup_lines' checked \(\d+\.\ds\); starting its nodes", line)
    )
    ready = [i for i, line in enumerate(lines) if line.startswith("ready: ")]
    done = next(i for i, line in enumerate(lines) if line.startswith("all nodes ready after "))
    assert 0 < checked < min(ready) and max(ready) < done
    said = sorted(re.match(r"ready: (\w+)(?: \(process (\w+)\))?, (\d)/3, \d+\.\ds$", lines[i]).groups() for i in ready)
    assert said == [("scale", "pair", said[0][2]), ("sink", "pair", said[1][2]), ("source", None, said[2][2])]
    assert sorted(n for *_, n in said) == ["1", "2", "3"]  # each node once, counted in order
    assert re.fullmatch(r"all nodes ready after \d+\.\ds \(\d+\.\ds after the command\)", lines[done])
