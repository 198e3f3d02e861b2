"""The plugin of docs/pipelines.md, registered through a real entry point, runs in a graph."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from handflow.framework.testkit.plugin_dist import register_plugins

DOC = Path(__file__).resolve().parents[2] / "docs" / "pipelines.md"


def install_doc_plugin(tmp_path: Path) -> dict[str, str]:
    """Write the doc's plugin module and the dist-info metadata pip would write; return the env."""
    code = re.search(r"```python\n(# my_plugins/threshold.py\n.*?)```", DOC.read_text(), re.S).group(1)
    pkg = tmp_path / "my_plugins"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "threshold.py").write_text(code)
    toml = re.search(r'```toml\n\[project.entry-points."handflow.plugins"\]\n(.*?)```', DOC.read_text(), re.S).group(1)
    entries = dict(line.replace('"', "").split(" = ") for line in toml.splitlines() if line.strip())
    return register_plugins(tmp_path, "my_plugins", entries)


def test_doc_plugin_is_listed_and_runs(tmp_path, run_handflow):
    handflow = run_handflow
    env = install_doc_plugin(tmp_path)
    listed = handflow("plugins", "--json", env=env, check=True)
    info = {p["name"]: p for p in json.loads(listed.stdout)}
    assert info["mine.threshold"]["inputs"] == {"in": "handflow.Array"}
    graph = tmp_path / "g.yaml"
    graph.write_text(
        "name: thr\nnodes:\n  - id: src\n    plugin: basic.signal\n    params: {rate_hz: 50}\n"
        "  - id: thr\n    plugin: mine.threshold\n    params: {level: 0.0}\n    inputs: {in: src/out}\n"
        "  - id: sink\n    plugin: basic.sink\n    params: {jsonl: out.jsonl}\n    inputs: {in: thr/label}\n"
    )
    proc = handflow("run", str(graph), "--duration", "2.5", env=env, check=True, cwd=tmp_path)
    assert "labelled" in proc.stderr  # the plugin's teardown ran
    labels = {json.loads(line)["msg"]["label"] for line in (tmp_path / "out.jsonl").read_text().splitlines()}
    assert labels == {"high", "low"}


@pytest.mark.parametrize("cmd", [["validate", "configs/basic_chain.yaml"], ["plugins", "basic.signal"]])
def test_doc_commands(cmd, run_handflow):
    run_handflow(*cmd, check=True)
