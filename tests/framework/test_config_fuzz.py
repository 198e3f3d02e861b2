"""Structure-aware mutation fuzzing of the shipped graphs and configs (docs/reliability.md).

Every mutated file is either accepted or rejected with the loader's own error — for graphs, every
problem carries a line inside the file and ``handflow validate`` exits 2 — never a traceback.
``HANDFLOW_FUZZ_EXAMPLES`` raises the number of examples per file (CI runs the default).
"""

from __future__ import annotations

import math
import os
import random
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from handflow.framework.graphs.model import read_graph_text, validate_file
from handflow.plugins.manifold.cli import load_config
from handflow.plugins.manifold.validation import InvalidInputError
from handflow.plugins.mapping.calibration import CalibrationFileError, load_calibration, load_profile

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
GRAPHS = sorted(CONFIGS.glob("*.yaml")) + [CONFIGS / "grasp" / "experience_grasp.yaml"]
EXAMPLES = int(os.environ.get("HANDFLOW_FUZZ_EXAMPLES", "60"))
FUZZ = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])

ODD_VALUES = [
    None, 0, -1, 1e308, -1e308, math.nan, math.inf, 2**70, True, "", "x" * 5000, "../../etc/passwd",
    "\x00\x01", "ünïcödé", [], {}, [[[]]], {"a": {"b": {"c": None}}}, [1, "two", None], 3.5, "1e400",
]  # fmt: skip


def _paths(node, prefix=()):
    """Every path into a YAML tree (mapping keys and list indices)."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, (*prefix, i))


def _mutate_tree(data, rng: random.Random):
    """One structural change: delete, replace, rename a key, duplicate an entry or wrap a value."""
    paths = [p for p in _paths(data) if p]
    if not paths:
        return rng.choice(ODD_VALUES)
    path = rng.choice(paths)
    parent = data
    for key in path[:-1]:
        parent = parent[key]
    key = path[-1]
    op = rng.randrange(5)
    if op == 0:
        del parent[key]
    elif op == 1:
        parent[key] = rng.choice(ODD_VALUES)
    elif op == 2 and isinstance(parent, dict):
        parent[rng.choice(["", "unknown_key", "id", "plugin", "nodes", str(key) + "_"])] = parent.pop(key)
    elif op == 3 and isinstance(parent, list):
        parent.insert(rng.randrange(len(parent) + 1), parent[key])
    else:
        parent[key] = [parent[key]] if rng.random() < 0.5 else {"value": parent[key]}
    return data


def _mutate_text(text: str, rng: random.Random) -> str:
    """One textual change: cut, drop or duplicate a line, or insert YAML punctuation."""
    lines = text.splitlines(keepends=True) or [""]
    op = rng.randrange(4)
    i = rng.randrange(len(lines))
    if op == 0:
        return text[: rng.randrange(len(text) + 1)]
    if op == 1:
        del lines[i]
    elif op == 2:
        lines.insert(i, lines[i])
    else:
        pos = rng.randrange(len(lines[i]) + 1)
        lines[i] = (
            lines[i][:pos]
            + rng.choice([":", "- ", "[", "{", "'", '"', "\t", "&a ", "*a", "!!python/object "])
            + lines[i][pos:]
        )
    return "".join(lines)


def mutated(text: str, seed: int) -> str:
    rng = random.Random(seed)
    out = text
    for _ in range(rng.randint(1, 3)):
        if rng.random() < 0.6:
            data = yaml.safe_load(out)
            try:
                out = yaml.safe_dump(_mutate_tree(data, rng), sort_keys=False, allow_unicode=True)
            except (AttributeError, TypeError, KeyError, IndexError, RecursionError):
                out = _mutate_text(out, rng)  # the text no longer parses to a tree: mutate it as text
        else:
            out = _mutate_text(out, rng)
        try:
            yaml.safe_load(out)
        except yaml.YAMLError:
            break  # a syntax error: further tree mutations are impossible
    return out


@pytest.mark.parametrize("graph", GRAPHS, ids=lambda p: p.name)
@FUZZ
@given(seed=st.integers(0, 2**32 - 1))
def test_mutated_graphs_are_accepted_or_rejected_with_a_line(graph, seed):
    text = mutated(graph.read_text(), seed)
    n_lines = text.count("\n") + 1
    result, problems = read_graph_text(text, graph)  # must not raise
    assert (result is None) == bool(problems)
    for p in problems:
        assert 1 <= p.line <= n_lines and p.message.strip(), p


@FUZZ
@given(seed=st.integers(0, 2**32 - 1))
def test_validate_exits_0_or_2_on_mutated_files(tmp_path_factory, seed):
    graph = GRAPHS[seed % len(GRAPHS)]
    path = tmp_path_factory.mktemp("g") / graph.name
    path.write_text(mutated(graph.read_text(), seed), encoding="utf-8")
    _, problems = validate_file(path)  # what `handflow validate` prints and turns into exit 2
    assert all(isinstance(p.line, int) for p in problems)


TRAIN_CONFIGS = sorted((CONFIGS / "train").glob("*.yaml"))


@pytest.mark.parametrize("config", TRAIN_CONFIGS, ids=lambda p: p.name)
@FUZZ
@given(seed=st.integers(0, 2**32 - 1))
def test_mutated_training_configs_load_or_raise_a_clear_error(tmp_path_factory, config, seed):
    path = tmp_path_factory.mktemp("c") / config.name
    path.write_text(mutated(config.read_text(), seed), encoding="utf-8")
    try:
        load_config(path)
    except InvalidInputError as exc:
        assert str(path) in str(exc) or path.name in str(exc)


@pytest.mark.parametrize(
    "source, loader",
    [("default_calibration.yaml", load_calibration), ("default_profile.yaml", load_profile)],
    ids=["calibration", "profile"],
)
@FUZZ
@given(seed=st.integers(0, 2**32 - 1))
def test_mutated_calibrations_and_profiles_load_or_raise_a_clear_error(tmp_path_factory, source, loader, seed):
    path = tmp_path_factory.mktemp("p") / source
    path.write_text(mutated((CONFIGS / "glove" / source).read_text(), seed), encoding="utf-8")
    try:
        loader(path)
    except CalibrationFileError as exc:
        assert str(path) in str(exc)


def test_an_input_from_an_external_topic_of_unknown_type_is_one_problem_not_a_crash(tmp_path):
    text = """name: g
external: {shadow/joints: handflow.NoSuchType}
nodes:
  - id: sink
    plugin: basic.sink
    inputs: {in: shadow/joints}
"""
    graph, problems = read_graph_text(text, tmp_path / "g.yaml")  # found by the fuzzer above
    assert graph is None and [p.line for p in problems] == [2]
    assert "unknown message type 'handflow.NoSuchType'" in problems[0].message
