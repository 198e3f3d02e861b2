"""Preflight and honest exit status (docs/pipelines.md "Inputs", docs/reliability.md "Exit status"):
the real CLI on real graphs — a missing input is refused at validation with its graph line, a node
failing at run time is summarised with its own message, and a deterministic setup failure is a
crash loop within seconds."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import REPO, handflow

pytestmark = pytest.mark.slow

HIDE_LSL = "import sys; sys.modules['mne_lsl'] = None; from handflow.framework.cli import main; sys.exit(main())"
"""The real CLI in an interpreter where mne-lsl counts as not installed."""


def _som_file(path: Path) -> None:
    """An npz of another handflow format (a grasp SOM's metadata), not a manifold."""
    np.savez(path, metadata=np.array(json.dumps({"format": "handflow.grasp_som", "format_version": 1})))


# (case, node entry, file to create or None, words the message must hold)
CASES = [
    (
        "missing CSV",
        "plugin: basic.signal\n    params:\n      kind: csv\n      csv: rows.csv",
        None,
        "CSV file rows.csv",
    ),
    (
        "missing model directory",
        "plugin: segmenter.ukr_only\n    params:\n      models: trained/",
        None,
        "handflow train-classes",
    ),
    (
        "model file of the wrong format",
        "plugin: manipulation.open_loop\n    params:\n      latent: [0.0]\n      manifold: som.npz",
        _som_file,
        "not a handflow manipulation manifold file (format 'handflow.grasp_som')",
    ),
    (
        "missing serial port",
        "plugin: glove.cyberglove\n    params:\n      port: /dev/handflow-no-such-glove",
        None,
        "glove device /dev/handflow-no-such-glove: no such device",
    ),
    ("missing extra", "plugin: lsl.inlet\n    params:\n      name: emg", None, "pip install 'handflow[lsl]'"),
]


def _graph(tmp_path: Path, entries: list[str]) -> tuple[Path, list[int]]:
    """A graph with a sink and one node per entry; returns it and the line of each entry's input
    parameter (for a missing extra: its plugin line)."""
    text = "name: preflight\nnodes:\n  - id: sink\n    plugin: basic.sink\n"
    text += "".join(f"  - id: n{i}\n    {entry}\n" for i, entry in enumerate(entries))
    path = tmp_path / "graph.yaml"
    path.write_text(text)
    marks = ("csv:", "models:", "manifold:", "port:", "calibration:", "plugin: lsl.")
    lines = [k for k, line in enumerate(text.splitlines(), 1) if line.strip().startswith(marks)]
    return path, lines


def _cli(*args: str, case: str = "", cwd: Path = REPO, timeout: float = 120) -> subprocess.CompletedProcess:
    if case != "missing extra":
        return handflow(*args, cwd=cwd, timeout=timeout)
    return subprocess.run(
        [sys.executable, "-c", HIDE_LSL, *args], capture_output=True, text=True, cwd=cwd, timeout=timeout
    )


@pytest.mark.parametrize("case, entry, make, words", CASES, ids=[c[0] for c in CASES])
def test_a_missing_input_is_refused_before_anything_starts(tmp_path, case, entry, make, words):
    if make is not None:
        make(tmp_path / "som.npz")
    graph, [line] = _graph(tmp_path, [entry])
    for cmd in (["validate", str(graph)], ["run", str(graph), "--duration", "2"]):
        proc = _cli(*cmd, case=case)
        assert proc.returncode == 2, (cmd, proc.stderr)
        assert f"{graph}:{line}: node 'n0'" in proc.stderr
        assert words in proc.stderr
        assert "Traceback" not in proc.stderr
        assert "started" not in proc.stderr  # run: no process was launched


MODELS = "plugin: segmenter.online_clm\n    params:\n      models: trained"
# (case, files to write, node entry, words the message must hold)
UNLOADABLE = [
    (
        "broken classes.json",
        {"trained/classes.json": '{"classes": {"grasp": '},
        MODELS,
        "classes.json: inconsistent class index file (JSONDecodeError",
    ),
    (
        "garbage model file",
        {"trained/classes.json": '{"classes": {"grasp": "grasp.npz"}}', "trained/grasp.npz": "not a zip"},
        MODELS,
        "grasp.npz: not a class model file",
    ),
    (
        "model file missing",
        {"trained/classes.json": '{"classes": {"grasp": "gone.npz"}}'},
        MODELS,
        "not found; train them with `handflow train-classes",
    ),
    (
        "broken calibration",
        {"calib.yaml": "lower: [1, 2\n"},
        "plugin: mapping.human_hand\n    params:\n      calibration: calib.yaml",
        "calib.yaml:2: YAML syntax error",
    ),
]


@pytest.mark.parametrize("case, files, entry, words", UNLOADABLE, ids=[c[0] for c in UNLOADABLE])
def test_a_file_the_node_cannot_load_is_refused_before_anything_starts(tmp_path, case, files, entry, words):
    """The plugin's own preflight reads what the node reads at start (a models folder's index and
    each model's metadata, a calibration), without building anything: validate and run exit 2 at
    the parameter's line instead of a crash loop at run time."""
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text(text)
    graph, [line] = _graph(tmp_path, [entry])
    for cmd in (["validate", str(graph)], ["run", str(graph), "--duration", "2"]):
        proc = handflow(*cmd, cwd=tmp_path)
        assert proc.returncode == 2, (cmd, proc.stderr)
        assert f"{graph}:{line}: node 'n0' (" in proc.stderr and words in proc.stderr
        assert "started" not in proc.stderr and "Traceback" not in proc.stderr


def test_validate_lists_every_failure_at_once(tmp_path):
    _som_file(tmp_path / "som.npz")
    graph, lines = _graph(tmp_path, [entry for case, entry, _, _ in CASES if case != "missing extra"])
    proc = handflow("validate", str(graph))
    assert proc.returncode == 2
    reported = [int(m) for m in re.findall(rf"^{re.escape(str(graph))}:(\d+): ", proc.stderr, re.M)]
    assert reported == lines
    assert f"{len(lines)} problem(s)" in proc.stderr


def test_run_help_lists_the_exit_codes():
    text = " ".join(handflow("run", "--help", check=True).stdout.split())
    assert "3 a node in a crash loop, 4 a node failed and was not running at the end" in text


def _bad_csv_graph(tmp_path: Path, restart: str = "") -> Path:
    """A CSV source whose file exists (preflight passes) but holds no numbers: it fails during setup."""
    (tmp_path / "rows.csv").write_text("a,b\nx,y\n")
    graph = tmp_path / "graph.yaml"
    graph.write_text(
        "name: runtime_failure\nnodes:\n  - id: sink\n    plugin: basic.sink\n    inputs: {in: src/out}\n"
        f"  - id: src\n    plugin: basic.signal\n    params: {{kind: csv, csv: rows.csv, rate_hz: 50}}\n{restart}"
    )
    return graph


def _stamp(line: str) -> float:
    return datetime.strptime(line[:23], "%Y-%m-%d %H:%M:%S,%f").timestamp()


def test_a_node_failing_during_setup_twice_alike_is_a_crash_loop_within_seconds(tmp_path):
    graph = _bad_csv_graph(tmp_path)
    proc = handflow("run", str(graph), "--duration", "2", cwd=tmp_path)
    assert proc.returncode == 3, proc.stderr
    log = proc.stderr.splitlines()
    # the rule: the second failure with the same setup error is the crash loop (no third start)
    assert sum("started src" in line for line in log) == 2
    first = next(line for line in log if "src failed during setup" in line)
    loop = next(line for line in log if "crash loop: src failed during setup 2 times with the same error" in line)
    assert _stamp(loop) - _stamp(first) <= 10.0
    assert "Traceback" not in proc.stderr
    assert "all nodes ready" not in proc.stderr
    summary = f"{graph}:6: src (crash loop after 2 failed starts, not restarted): failed 2 times with the same error"
    assert summary in proc.stderr
    # the node's message once, as it happens; the summary gives its graph line and the count
    message = "not numeric CSV rows under a header row"
    assert message in first and proc.stderr.count(message) == 1, proc.stderr


def test_a_failed_node_down_at_the_end_exits_4_with_its_own_message(tmp_path):
    graph = _bad_csv_graph(tmp_path, "    restart: {policy: never}\n")
    proc = handflow("run", str(graph), "--duration", "2", cwd=tmp_path)
    assert proc.returncode == 4, proc.stderr
    assert f"{graph}:6: src (not running at the end): failed during setup: node 'src': " in proc.stderr
    assert "fix the file" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert "all nodes ready" not in proc.stderr
    assert "the other nodes start without src" in proc.stderr  # the sink still runs its duration


def test_a_node_that_restarted_and_runs_at_the_end_exits_0_noted_in_the_summary(tmp_path):
    graph = _bad_csv_graph(tmp_path, "    restart: {backoff_s: 2.0}\n")
    proc = subprocess.Popen(
        [sys.executable, "-m", "handflow.framework.cli", "run", str(graph), "--duration", "2"],
        cwd=tmp_path,
        stderr=subprocess.PIPE,
        text=True,
    )
    err = []
    deadline = time.monotonic() + 60
    for line in proc.stderr:
        err.append(line)
        if "src failed during setup" in line:
            (tmp_path / "rows.csv").write_text("a,b\n1,2\n3,4\n")  # fixed during the backoff
        assert time.monotonic() < deadline, "".join(err)
    assert proc.wait(timeout=60) == 0, "".join(err)
    stderr = "".join(err)
    assert f"{graph}:6: src (restarted 1x, running at the end): failed during setup" in stderr
    assert "all nodes ready" in stderr
    assert stderr.index("src failed during setup") < stderr.index("all nodes ready")


def test_the_declarations_of_docs_pipelines_md_are_checked_for_a_user_plugin(tmp_path):
    doc = (REPO / "docs" / "pipelines.md").read_text()
    code = re.search(r"### Inputs.*?```python\n(.*?)```", doc, re.S).group(1)
    ns: dict = {}
    src = "from handflow.framework.files.params import StrictModel\nfrom handflow.framework.plugin import Node\n" + code
    exec(compile(src, "docs/pipelines.md", "exec", dont_inherit=True), ns)  # without this module's __future__
    from handflow.framework.files.inputs import node_input_problems

    params = ns["Params"](table="t.csv", models="m", weights="w.npz", port="/dev/handflow-no-such-sensor")
    assert [loc for loc, _ in node_input_problems(ns["MyNode"], params, tmp_path)] == [
        ("table",),
        ("models",),
        ("weights",),
        ("port",),
    ]
    (tmp_path / "t.csv").write_text("a\n1\n")
    (tmp_path / "m").mkdir()
    np.savez(tmp_path / "w.npz", metadata=np.array(json.dumps({"format": "my.weights", "version": 2})))
    params = ns["Params"](table="t.csv", models="m", weights="w.npz")
    assert node_input_problems(ns["MyNode"], params, tmp_path) == [
        (
            ("weights",),
            f"{tmp_path / 'w.npz'}: weights file format version 2, this handflow reads version 1; "
            "make one with `mytool fit`",
        )
    ]
