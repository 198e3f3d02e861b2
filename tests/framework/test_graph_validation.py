"""`handflow validate`: every kind of bad graph gives exit code 2 and a message with its line."""

from __future__ import annotations

import textwrap

import pytest

from handflow.framework.graphs.model import GraphError, load_graph, validate_file

GOOD = """\
name: chain
nodes:
  - id: source
    plugin: basic.signal
    params: {rate_hz: 10}
  - id: scale
    plugin: basic.transform
    inputs: {in: source/out}
  - id: sink
    plugin: basic.sink
    inputs: {in: scale/out}
"""

BAD = {
    "yaml_syntax": ("name: x\nnodes:\n  - id: a\n   plugin: basic.sink\n", 4, "YAML syntax"),
    "unknown_plugin": ("name: x\nnodes:\n  - id: a\n    plugin: basic.nope\n", 4, "basic.signal"),
    "param_type": (
        "name: x\nnodes:\n  - id: a\n    plugin: basic.signal\n    params:\n      rate_hz: fast\n",
        6,
        "rate_hz",
    ),
    "unknown_param": (
        "name: x\nnodes:\n  - id: a\n    plugin: basic.signal\n    params:\n      speed: 3\n",
        6,
        "speed",
    ),
    "duplicate_id": (
        "name: x\nnodes:\n  - id: a\n    plugin: basic.sink\n  - id: a\n    plugin: basic.sink\n",
        5,
        "duplicate node id",
    ),
    "missing_node": (
        "name: x\nnodes:\n  - id: a\n    plugin: basic.sink\n    inputs:\n      in: ghost/out\n",
        6,
        "missing node 'ghost'",
    ),
    "missing_port": (
        "name: x\nnodes:\n  - id: s\n    plugin: basic.signal\n  - id: a\n    plugin: basic.sink\n"
        "    inputs:\n      in: s/nope\n",
        8,
        "no output 'nope'",
    ),
    "bad_input_port": (
        "name: x\nnodes:\n  - id: s\n    plugin: basic.signal\n  - id: a\n    plugin: basic.transform\n"
        "    inputs:\n      input: s/out\n",
        8,
        "no input port 'input'",
    ),
    "type_mismatch": (
        "name: x\nexternal:\n  glove/joints: JointState\nnodes:\n  - id: a\n    plugin: basic.transform\n"
        "    inputs:\n      in: glove/joints\n",
        8,
        "expects handflow.Array",
    ),
    "status_topic": (
        "name: x\nnodes:\n  - id: s\n    plugin: basic.signal\nstatus:\n  topic: s/nope\n  field: label\n",
        6,
        "status.topic 's/nope' is not an output",
    ),
    "status_field": (
        "name: x\nnodes:\n  - id: s\n    plugin: basic.signal\nstatus:\n  topic: s/out\n  field: data\n",
        7,
        "handflow.Array has no such scalar field",
    ),
    "missing_field": ("name: x\nnodes:\n  - plugin: basic.sink\n", 3, "id: required field"),
    "transport_local": (
        "name: x\ntransport:\n  local: shm\nnodes:\n  - id: a\n    plugin: basic.sink\n",
        3,
        "transport.local: Input should be 'iceoryx2' or 'zenoh'",
    ),
}


def write(tmp_path, text):
    p = tmp_path / "graph.yaml"
    p.write_text(textwrap.dedent(text))
    return p


def test_good_graph_validates(tmp_path, run_handflow):
    graph = load_graph(write(tmp_path, GOOD))
    assert list(graph.nodes) == ["source", "scale", "sink"]
    assert graph.subscribers("scale/out") == [("sink", "in")]
    proc = run_handflow("validate", str(tmp_path / "graph.yaml"))
    assert proc.returncode == 0, proc.stderr


def test_cycles_are_allowed(tmp_path):
    text = (
        "name: loop\nnodes:\n  - id: a\n    plugin: basic.transform\n    inputs: {in: b/out}\n"
        "  - id: b\n    plugin: basic.transform\n    inputs: {in: a/out}\n"
    )
    assert validate_file(write(tmp_path, text))[1] == []


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_graph_reports_line_and_fix(tmp_path, case):
    text, line, needle = BAD[case]
    graph, problems = validate_file(write(tmp_path, text))
    assert graph is None
    assert any(p.line == line and needle in p.message for p in problems), problems
    with pytest.raises(GraphError):
        load_graph(tmp_path / "graph.yaml")


def test_validate_cli_exit_code_and_every_problem(tmp_path, run_handflow):
    text = (
        "name: x\nnodes:\n  - id: a\n    plugin: basic.nope\n  - id: b\n    plugin: basic.signal\n"
        "    params: {rate_hz: fast}\n  - id: c\n    plugin: basic.sink\n    inputs: {in: ghost/out}\n"
    )
    path = write(tmp_path, text)
    proc = run_handflow("validate", str(path))
    assert proc.returncode == 2
    assert f"{path}:4:" in proc.stderr and "unknown plugin 'basic.nope'" in proc.stderr
    assert f"{path}:7:" in proc.stderr and "rate_hz" in proc.stderr
    assert f"{path}:10:" in proc.stderr and "ghost" in proc.stderr


FIVE_MISTAKES = """\
name: five
nodes:
  - id: source
    plugin: basic.signal
    params: {rate_hz: fast}
  - id: scale
    plugin: basic.transform
    inputs: {in: source/outt}
  - id: ctrl
    plugin: manipulation.open_loop
    params:
      manifold: broken.npz
  - id: sink
    plugin: basic.snk
    inputs: {in: scale/out}
"""


def test_validate_reports_five_mistakes_in_one_graph_as_five_lines_in_file_order(tmp_path, run_handflow):
    """A failed parameter hides neither the node's wrong input port nor its unreadable model file."""
    (tmp_path / "broken.npz").write_text("not a zip")
    path = write(tmp_path, FIVE_MISTAKES)
    proc = run_handflow("validate", str(path))
    assert proc.returncode == 2
    reported = [
        line for line in proc.stderr.splitlines() if line.startswith(f"{path}:") and ": " in line[len(str(path)) + 1 :]
    ]
    expected = [
        (5, "node 'source' param rate_hz: Input should be a valid number"),
        (8, "node 'scale' input 'in': node 'source' has no output 'outt'; its outputs: out"),
        (11, "node 'ctrl' param latent: required field is missing"),
        (12, "broken.npz: not a manipulation manifold file"),
        (14, "unknown plugin 'basic.snk'; did you mean 'basic.sink'"),
    ]
    assert len(reported) == len(expected), proc.stderr
    for line, (no, words) in zip(reported, expected):
        assert line.startswith(f"{path}:{no}: ") and words in line, (line, no, words)
    assert proc.stderr.rstrip().endswith(f"{path}: 5 problem(s)")


def test_a_bad_top_level_field_or_node_entry_hides_no_other_problem(tmp_path):
    text = (
        "name: x\nrecord: {topics: 3}\nnodes:\n  - id: bad id\n    plugin: basic.sink\n"
        "  - id: a\n    plugin: basic.signal\n    params: {rate_hz: fast}\n"
        "  - id: b\n    plugin: basic.sink\n    inputs: {in: ghost/out}\n"
    )
    graph, problems = validate_file(write(tmp_path, text))
    assert graph is None
    assert [(p.line, p.message.split(":")[0]) for p in problems] == [
        (2, "record.topics"),
        (4, "nodes.0.id"),
        (8, "node 'a' param rate_hz"),
        (11, "node 'b' input 'in' reads from missing node 'ghost'; existing nodes"),
    ]


def test_a_misspelt_plugin_name_gets_a_did_you_mean(tmp_path, run_handflow):
    path = write(tmp_path, "name: x\nnodes:\n  - id: a\n    plugin: basic.signl\n")
    proc = run_handflow("validate", str(path))
    assert proc.returncode == 2
    assert f"{path}:4: unknown plugin 'basic.signl'; did you mean 'basic.signal'" in proc.stderr
    listed = run_handflow("plugins", "segmenter.onlineclm")
    assert listed.returncode == 2 and "did you mean 'segmenter.online_clm'" in listed.stderr


def test_run_refuses_invalid_graph(tmp_path, run_handflow):
    proc = run_handflow("run", str(write(tmp_path, BAD["unknown_plugin"][0])), "--duration", "1")
    assert proc.returncode == 2
    assert "unknown plugin" in proc.stderr
