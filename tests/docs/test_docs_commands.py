"""Every shell command in the user docs runs (every command in the docs is exercised).

The commands are the lines of the fenced ```bash blocks and the ``$ `` lines of the ```console
blocks of README.md and docs/*.md.  docs/recording.md and docs/monitoring.md are run by
tests/framework/test_recording_docs.py and skipped here.  A comment right before a block adapts
it for the test (it stays invisible in rendered Markdown):

- ``<!-- doc-test: skip REASON -->``: the block is not run (hardware);
- ``<!-- doc-test: sub "OLD" => "NEW" -->``: replace text in the block's commands (a bounded
  variant, e.g. ``--duration``); several may precede one block;
- ``<!-- doc-test: drop "TEXT" REASON -->``: leave out the commands containing TEXT;
- ``<!-- doc-test: needs "MODULE" -->``: the block (and the graphs it names) is checked only where
  MODULE imports (an optional extra, e.g. ``mne_lsl`` of ``handflow[lsl]``);
- ``<!-- doc-test: file "PATH" -->`` before a block of any language: the page asks the reader to save
  that block as PATH, so the test writes it there before running the page's next command.

Commands run in order, per document, with ``bash`` in a scratch copy of ``configs/``, ``docs/``
and ``recordings/`` (so nothing in the repository changes); ``handflow`` and ``python`` are this
interpreter.  ``CMD &`` starts a background job (waited for until its graph's run-file appears),
``kill -INT %N`` stops job N and requires exit code 0.
"""

from __future__ import annotations

import configparser
import importlib.util
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import yaml

from handflow.framework.discovery import live_runs
from handflow.framework.graph import load_graph

REPO = Path(__file__).resolve().parents[2]
TESTED_ELSEWHERE = {"recording.md", "monitoring.md"}  # tests/framework/test_recording_docs.py
FROM_ANY_DIRECTORY = {"tutorial_training.md"}  # run from an empty directory below, outcome asserted
AWAITING_MARKERS = {"grasping.md": "its commands run ~10 min as written; needs doc-test markers for bounded variants"}
"""Documents whose owners have not yet added the markers that bound their commands (reported to the lead)."""
MULTI_PROCESS = ("handflow run", "handflow replay", "handflow calibrate --port", "&")
FENCE = re.compile(r"^```(\w*)\s*$")
MARKER = re.compile(r"^<!--\s*doc-test:\s*(skip|sub|drop|needs|file)\b(.*?)-->\s*$")
QUOTED = re.compile(r'"((?:[^"\\]|\\.)*)"')


@dataclass
class Block:
    doc: str
    line: int
    commands: list[str]
    markers: list[tuple[str, str]] = field(default_factory=list)
    text: str = ""

    def available(self) -> bool:
        """Whether every module named by a ``needs`` marker imports here."""
        return all(
            importlib.util.find_spec(QUOTED.findall(arg)[0]) is not None
            for kind, arg in self.markers
            if kind == "needs"
        )

    def runnable(self) -> list[str]:
        """The commands after the block's markers are applied ([] when skipped)."""
        if not self.available():
            return []
        commands = list(self.commands)
        for kind, arg in self.markers:
            quoted = QUOTED.findall(arg)
            if kind == "skip":
                return []
            if kind == "sub":
                old, new = quoted[0], quoted[1]
                assert any(old in c for c in commands), f"{self.doc}:{self.line}: sub '{old}' matches nothing"
                commands = [c.replace(old, new) for c in commands]
            elif kind == "drop":
                commands = [c for c in commands if quoted[0] not in c]
        return commands


def doc_blocks(path: Path) -> list[Block]:
    """The ```bash / ```console blocks of one Markdown file, with the markers right before them."""
    blocks, markers, lang, body, start = [], [], None, [], 0
    for no, line in enumerate(path.read_text().splitlines(), 1):
        if lang is None:
            if m := MARKER.match(line.strip()):
                markers.append((m.group(1), m.group(2).strip()))
            elif m := FENCE.match(line):
                lang, body, start = m.group(1), [], no
            elif line.strip():
                markers = []
            continue
        if not FENCE.match(line):
            body.append(line)
            continue
        if lang in ("bash", "console"):
            blocks.append(Block(path.name, start, _commands(lang, body), markers))
        elif any(kind == "file" for kind, _ in markers):
            blocks.append(Block(path.name, start, [], markers, "\n".join(body) + "\n"))
        lang, markers = None, []
    return blocks


def _commands(lang: str, body: list[str]) -> list[str]:
    if lang == "console":
        return [line[2:].strip() for line in body if line.startswith("$ ")]
    text = "\n".join(body).replace("\\\n", " ")
    return [line.strip() for line in text.splitlines() if line.strip() and not line.strip().startswith("#")]


def documents() -> list[Path]:
    skip = TESTED_ELSEWHERE | FROM_ANY_DIRECTORY | set(AWAITING_MARKERS)
    return [REPO / "README.md"] + sorted(p for p in (REPO / "docs").glob("*.md") if p.name not in skip)


def _params():
    out = []
    for path in documents():
        commands = [c for b in doc_blocks(path) for c in b.runnable()]
        if commands:
            slow = any(k in c for c in commands for k in MULTI_PROCESS)
            out.append(pytest.param(path, marks=[pytest.mark.slow] if slow else [], id=path.name))
    return out


# ----------------------------------------------------------------------------------------------
# fast checks
# ----------------------------------------------------------------------------------------------
def test_markers_and_blocks_are_well_formed():
    for path in documents():
        for block in doc_blocks(path):
            block.runnable()  # a stale 'sub' fails here
            for kind, arg in block.markers:
                assert kind == "skip" or len(QUOTED.findall(arg)) >= (2 if kind == "sub" else 1), (path, arg)


def test_graph_files_named_in_doc_commands_validate():
    graphs = set()
    for path in documents() + [REPO / "docs" / d for d in TESTED_ELSEWHERE | FROM_ANY_DIRECTORY]:
        for block in filter(Block.available, doc_blocks(path)):
            for cmd in block.commands:
                graphs |= {w for w in shlex.split(cmd.rstrip("&")) if w.endswith(".yaml") and "/" in w}
    graphs = {g for g in graphs if (REPO / g).is_file()}  # not files the commands write
    graphs = {g for g in graphs if "nodes" in (yaml.safe_load((REPO / g).read_text()) or {})}  # not training configs
    assert len(graphs) >= 5, graphs
    for g in sorted(graphs):
        load_graph(REPO / g)


def test_foxglove_layout_topics_are_published_by_the_flagship():
    layout = json.loads((REPO / "docs" / "foxglove_layout.json").read_text())
    graph = load_graph(REPO / "configs" / "demo.yaml")
    text = json.dumps(layout["configById"])
    topics = set(re.findall(r"demo/(\w+)/(\w+)", text))
    assert topics
    for node, port in topics:
        assert port in graph.nodes[node].cls.outputs, f"{node}/{port}"
    assert set(re.findall(r'"([A-Za-z0-9]+![a-z]+)"', json.dumps(layout["layout"]))) == set(layout["configById"])


# ----------------------------------------------------------------------------------------------
# running the commands
# ----------------------------------------------------------------------------------------------
@pytest.fixture
def workspace(tmp_path, monkeypatch):
    ws = tmp_path / "ws"
    for name in ("configs", "docs", "recordings"):
        shutil.copytree(REPO / name, ws / name, ignore=shutil.ignore_patterns("__pycache__"))
    (ws / "out").mkdir()
    shim = tmp_path / "bin"
    shim.mkdir()
    (shim / "handflow").write_text(f'#!/bin/sh\nexec "{sys.executable}" -m handflow.framework.cli "$@"\n')
    (shim / "python").write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
    for f in shim.iterdir():
        f.chmod(0o755)
    monkeypatch.setenv("PATH", f"{shim}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.setenv("HANDFLOW_RUN_DIR", str(tmp_path / "runs"))
    monkeypatch.setenv("PYTHONPATH", str(REPO))
    return ws


def _graph_name(ws: Path, cmd: str) -> str:
    graph = next(w for w in shlex.split(cmd) if w.endswith(".yaml"))
    return yaml.safe_load((ws / graph).read_text())["name"]


def _wait_started(name: str, count: int, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while sum(r.graph == name for r in live_runs()) < count:
        assert time.monotonic() < deadline, f"graph '{name}' did not start within {timeout:.0f}s"
        time.sleep(0.2)
    time.sleep(2.0)  # let its nodes come up


@pytest.mark.parametrize("doc", _params())
def test_documented_commands_run(doc, workspace):
    run_page(doc, workspace)


def run_page(doc: Path, workspace: Path) -> None:
    """Run the page's commands in order in ``workspace``, writing the blocks it asks to save."""
    jobs: list[subprocess.Popen] = []
    started: dict[str, int] = {}
    try:
        for block in doc_blocks(doc):
            for kind, arg in block.markers:
                if kind == "file":
                    (workspace / QUOTED.findall(arg)[0]).write_text(block.text)
            for cmd in block.runnable():
                where = f"{doc.name}:{block.line}: {cmd}"
                if kill := re.fullmatch(r"kill -INT %(\d+)", cmd):
                    job = jobs[int(kill.group(1)) - 1]
                    job.send_signal(signal.SIGINT)
                    out, err = job.communicate(timeout=60)
                    assert job.returncode == 0, f"{where}\n{out}\n{err}"
                elif cmd.endswith("&"):
                    name = _graph_name(workspace, cmd)
                    started[name] = started.get(name, 0) + 1
                    jobs.append(
                        subprocess.Popen(
                            ["bash", "-c", f"exec {cmd[:-1]}"],
                            cwd=workspace,
                            text=True,
                            stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE,
                        )
                    )
                    _wait_started(name, started[name])
                else:
                    proc = subprocess.run(
                        ["bash", "-c", cmd], cwd=workspace, capture_output=True, text=True, timeout=150
                    )
                    assert proc.returncode == 0, f"{where}\n{proc.stdout[-2000:]}\n{proc.stderr[-4000:]}"
    finally:
        for job in jobs:
            if job.poll() is None:
                job.kill()
                job.communicate()


@pytest.mark.slow
def test_the_training_tutorial_works_from_an_empty_directory(workspace):
    """docs/tutorial_training.md from a directory holding nothing of the checkout writes what it says."""
    elsewhere = workspace.parent / "elsewhere"
    elsewhere.mkdir()
    run_page(REPO / "docs" / "tutorial_training.md", elsewhere)
    out = elsewhere / "out"
    assert (out / "my_session.mcap").stat().st_size > 0
    assert sorted(p.name for p in (out / "my_plots").iterdir()) == ["latents.png", "manifold.png", "objective.png"]
    from handflow.plugins.manifold import StructuredUKR

    model = StructuredUKR.load(out / "my_manifold.npz")
    assert model.latents_.shape[1] == 1 and model.Y_.shape[1] == 24  # one latent time, 24 ShadowHand joints


def test_the_loopback_lsl_setup_shown_in_lsl_md_is_the_shipped_file():
    """docs/lsl.md shows docs/examples/lsl_api_loopback.cfg, which liblsl reads through LSLAPICFG."""
    shown = re.search(r"```ini\n(.*?)```", (REPO / "docs" / "lsl.md").read_text(), re.S).group(1)
    page, shipped = configparser.ConfigParser(), configparser.ConfigParser()
    page.optionxform = shipped.optionxform = str  # liblsl's keys are case-sensitive
    page.read_string(textwrap.dedent(shown))
    shipped.read(REPO / "docs" / "examples" / "lsl_api_loopback.cfg")
    assert {s: dict(page[s]) for s in page.sections()} == {s: dict(shipped[s]) for s in shipped.sections()}
    assert shipped["multicast"]["ResolveScope"] == "machine" and "127.0.0.1" in shipped["lab"]["KnownPeers"]
