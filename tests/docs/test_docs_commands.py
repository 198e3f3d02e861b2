"""Every shell command in the user docs runs, and the outcomes the pages state hold.

The commands are the lines of the fenced ```bash / ```sh blocks and the ``$ `` lines of the ```console
blocks of README.md and docs/*.md.  docs/recording.md and docs/monitoring.md are run by
tests/framework/test_recording_docs.py and skipped here.  A comment right before a block adapts
it for the test (it stays invisible in rendered Markdown):

- ``<!-- doc-test: skip REASON -->``: the block is not run (hardware);
- ``<!-- doc-test: sub "OLD" => "NEW" -->``: replace text in the block's commands (a bounded
  variant, e.g. ``--duration``); several may precede one block;
- ``<!-- doc-test: drop "TEXT" REASON -->``: leave out the commands containing TEXT;
- ``<!-- doc-test: needs "MODULE" -->``: the block (and the graphs it names) is checked only where
  MODULE imports (an optional extra, e.g. ``mne_lsl`` of ``handflow[lsl]``);
- ``<!-- doc-test: expect "TEXT" "CHECK ARG..." -->``: the outcome the page states for the
  commands containing TEXT (as written), asserted after they ran: a check of :data:`EXPECTATIONS`
  (arguments split like a shell line; ``sub`` markers apply to them too).  A command exits 0 unless
  its ``exit N`` check says otherwise.

- ``<!-- doc-test: busy REASON -->``: the block runs while a CPU hog holds one core (a busy machine);

- ``<!-- doc-test: file "PATH" -->`` before a block of any language: the page asks the reader to save
  that block as PATH, so the test writes it there before running the page's next command.

Every command that runs needs an ``expect`` (a background job ``CMD &`` is checked by its
``kill -INT %N``, whose ``expect`` markers see the job's output); a command that does not run says
why (``skip``/``drop`` REASON, ``needs``, :data:`TESTED_ELSEWHERE`).  A fenced block without a
language that holds commands must be ```bash or ```text (a synopsis).

Commands run in order, per document, with ``bash`` in a scratch copy of ``configs/``, ``docs/``
and ``recordings/`` (so nothing in the repository changes); ``handflow`` and ``python`` are this
interpreter.  ``CMD &`` starts a background job (waited for until its launcher says its nodes are up),
``kill -INT %N`` stops job N (numbered as bash numbers jobs: after
the highest one still running) and requires exit code 0.
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
import threading
import time
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import yaml

from handflow.framework.files.mcap_reader import iter_recording
from handflow.framework.graphs.model import load_graph
from tests.conftest import cpu_hog

REPO = Path(__file__).resolve().parents[2]
TESTED_ELSEWHERE = {"recording.md", "monitoring.md"}  # tests/framework/test_recording_docs.py
FROM_ANY_DIRECTORY = {"tutorial_training.md", "tutorial_gestures.md"}  # run from an empty directory below
BENCHMARKS = {
    "soak.py": "its bounded variant (1 min of the 60-minute soak) is tests/flagship/test_flagship_soak.py",
    "decode_fuzz.py": "its bounded variant is tests/framework/test_decode_robustness.py",
    "gesture_tutorial.py": "the page it times is run by test_the_gestures_tutorial_works_from_an_empty_directory",
    **dict.fromkeys(
        (
            f"{name}.py"
            for name in "calibration_curve clm_score_grouping enrolment_bound evaluation_cache evaluation_fold evaluation_scaling flagship"
            " glove_reader grasp"
            " manipulation param_roundtrip projection_kernel"
            " mapping_cost novelty_probe online_score_segmenter online_segmenter recording scorer_fit sim startup"
            " local_transport transport ukr_speed ukr_toy viewer watch_reload".split()
        ),
        "a measurement of this machine (minutes; figures and load in docs/benchmarks.md), not run by the tests",
    ),
}
"""The ``python benchmarks/X.py`` commands of the docs, in tables and prose: why the docs test does not run them."""
SLOW = (
    "handflow run",
    "handflow replay",
    "handflow calibrate --port",
    "&",
    "grasp-experience",
    "demo-record",
    "handflow evaluate segmentation",
)
"""Commands that mark their page's test slow: several processes, or a minute of computing."""
FENCE = re.compile(r"^```(\w*)\s*$")
JOB_STOP = re.compile(r"kill -INT %(\d+)")
RUN = ("bash", "sh", "console")
COMMAND = re.compile(r"^(\$ |handflow |python |pip )")
MARKER = re.compile(r"^<!--\s*doc-test:\s*(skip|sub|drop|needs|expect|file|busy)\b(.*?)-->\s*$")
QUOTED = re.compile(r'"((?:[^"\\]|\\.)*)"')


@dataclass
class Block:
    doc: str
    line: int
    commands: list[str]
    markers: list[tuple[str, str]] = field(default_factory=list)
    lang: str = "bash"
    text: str = ""  # the block's body, for a ``file`` marker

    def available(self) -> bool:
        """Whether every module named by a ``needs`` marker imports here."""
        return all(
            importlib.util.find_spec(QUOTED.findall(arg)[0]) is not None
            for kind, arg in self.markers
            if kind == "needs"
        )

    def plan(self) -> list[tuple[str, str]]:
        """The commands as written and as run, after the block's markers ([] when skipped)."""
        pairs = [(c, c) for c in self.commands]
        for kind, arg in self.markers:
            quoted = QUOTED.findall(arg)
            if kind == "skip":
                return []
            if kind == "sub":
                old, new = quoted[0], quoted[1]
                assert any(old in c for _, c in pairs), f"{self.doc}:{self.line}: sub '{old}' matches nothing"
                pairs = [(o, c.replace(old, new)) for o, c in pairs]
            elif kind == "drop":
                pairs = [(o, c) for o, c in pairs if quoted[0] not in o]
        return pairs

    def runnable(self) -> list[tuple[str, str]]:
        """:meth:`plan`, [] where a module named by ``needs`` is missing."""
        return self.plan() if self.available() else []

    def expectations(self, command: str) -> list[list[str]]:
        """The ``expect`` checks (name and arguments) of one of the block's commands, as written; the
        ``sub`` markers apply to the arguments too (a bounded variant writes elsewhere)."""
        marks = [(kind, [q.replace('\\"', '"') for q in QUOTED.findall(arg)]) for kind, arg in self.markers]
        checks = [q[1] for kind, q in marks if kind == "expect" and q[0] in command]
        for old, new in (q[:2] for kind, q in marks if kind == "sub"):
            checks = [c.replace(old, new) for c in checks]
        return [shlex.split(c) for c in checks]


@dataclass
class Outcome:
    """What one command did: its workspace, output and exit code (a ``kill``: its background job's)."""

    ws: Path
    stdout: str
    stderr: str
    code: int
    since: float  # when the command (or job) started


def _exit(o: Outcome, code: str) -> None:
    """The command exits with CODE (without this check: 0)."""
    assert o.code == int(code), f"exit {o.code}, expected {code}"


def _says(o: Outcome, *texts: str) -> None:
    """The command printed every TEXT (stdout or stderr, where the logs go)."""
    missing = [t for t in texts if t not in o.stdout + o.stderr]
    assert not missing, f"{missing} not printed:\n{o.stdout[-1500:]}\n{o.stderr[-1500:]}"


def _never(o: Outcome, *texts: str) -> None:
    """The command printed none of TEXTS (e.g. ``WARNING`` where the page says a normal run logs none)."""
    found = [line for line in (o.stdout + o.stderr).splitlines() if any(t in line for t in texts)]
    assert not found, "\n".join(found[:10])


def _json_field(o: Outcome, path: str, value: str) -> None:
    """stdout is JSON whose field PATH (dotted, list indices as numbers) is VALUE (JSON or a plain string)."""
    field = json.loads(o.stdout)
    for key in path.split("."):
        field = field[int(key)] if isinstance(field, list) else field[key]
    try:
        value = json.loads(value)
    except json.JSONDecodeError:
        pass
    assert field == value, f"{path} is {field!r}, expected {value!r}"


def _handflow_json(o: Outcome, *args: str) -> dict:
    proc = subprocess.run(["handflow", *args, "--json"], cwd=o.ws, capture_output=True, text=True, timeout=150)
    assert proc.stdout.strip(), f"handflow {' '.join(args)}: {proc.stderr[-2000:]}"
    return json.loads(proc.stdout)


def _files(o: Outcome, *files: str) -> None:
    """Every FILE (relative to the workspace) was written by the command and reads as its suffix says
    (MCAP, npz/npy, PNG, JSON, JSON lines, YAML)."""
    for name in files:
        path = o.ws / name
        assert path.is_file() and path.stat().st_size > 0, f"{name} not written"
        assert path.stat().st_mtime >= o.since - 1, f"{name} is older than the command"
        if path.suffix == ".mcap":
            assert _handflow_json(o, "inspect", name)["total_messages"] > 0, name
        elif path.suffix == ".npz":
            assert np.load(path).files, name
        elif path.suffix == ".npy":
            assert np.load(path).size, name
        elif path.suffix == ".png":
            assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
        elif path.suffix == ".json":
            json.loads(path.read_text())
        elif path.suffix == ".jsonl":
            assert [json.loads(line) for line in path.read_text().splitlines()], name
        elif path.suffix == ".yaml":
            assert yaml.safe_load(path.read_text()), name


def _topics_seen(o: Outcome, *topics: str) -> None:
    """``monitor --once --json`` printed every topic with a count > 0."""
    counts = {t["topic"]: t["count"] for t in json.loads(o.stdout)["topics"]}
    assert all(counts.get(t, 0) > 0 for t in topics), f"expected {topics}, seen {counts}"


def _nodes_alive(o: Outcome, *nodes: str) -> None:
    """``monitor --once --json`` printed every node, alive."""
    alive = {n["id"]: n["alive"] for n in json.loads(o.stdout)["nodes"]}
    assert all(alive.get(n) for n in nodes), f"expected {nodes} alive, seen {alive}"


def _recorded(o: Outcome, file: str, *topics: str) -> None:
    """The recording FILE holds messages of every TOPIC (``TOPIC=N``: exactly N) and, given ``channels=N``,
    messages on exactly N topics."""
    counts = {t["topic"]: t["count"] for t in _handflow_json(o, "inspect", file)["topics"]}
    for want in topics:
        name, _, n = want.partition("=")
        if name == "channels":
            assert len(counts) == int(n), f"{file}: {len(counts)} topics, expected {n}: {sorted(counts)}"
        else:
            got = counts.get(name, counts.get("/" + name, 0))
            assert (got == int(n)) if n else got > 0, f"expected {want} in {file}, recorded {counts}"


def _rate(o: Outcome, file: str, topic: str, hz: str) -> None:
    """TOPIC of the recording FILE has the rate HZ (within 10 %)."""
    rates = {t["topic"].lstrip("/"): t["rate_hz"] for t in _handflow_json(o, "inspect", file)["topics"]}
    assert abs(rates.get(topic, 0) - float(hz)) <= 0.1 * float(hz), f"{topic}: {rates.get(topic)} Hz, expected {hz}"


def _replayed_labels(o: Outcome, jsonl: str, mcap: str, topic: str) -> None:
    """The replay's JSON lines are the recording's labels on TOPIC: same count, index, label and stamp."""
    replayed = [json.loads(line)["msg"] for line in (o.ws / jsonl).read_text().splitlines()]
    live = [rm.decode() for rm in iter_recording(o.ws / mcap, [topic])]
    assert len(live) > 100 and len(replayed) == len(live), (len(live), len(replayed))
    for a, b in zip(live, replayed):
        assert (a.index, a.label, a.header.stamp_ns) == (b["index"], b["label"], b["header"]["stamp_ns"])


def _same_arrays(o: Outcome, a: str, b: str, *keys: str) -> None:
    """The .npz files A and B hold equal arrays under every KEY."""
    with np.load(o.ws / a) as x, np.load(o.ws / b) as y:
        for key in keys:
            np.testing.assert_array_equal(x[key], y[key], err_msg=f"{a}[{key}] != {b}[{key}]")


EXPECTATIONS = {
    "exit": _exit,
    "says": _says,
    "never": _never,
    "json": _json_field,
    "file": _files,
    "topics": _topics_seen,
    "nodes": _nodes_alive,
    "recorded": _recorded,
    "rate": _rate,
    "replayed": _replayed_labels,
    "same-arrays": _same_arrays,
}
"""Checks named by ``expect`` markers: called with the command's :class:`Outcome` and the arguments."""


def doc_blocks(path: Path) -> list[Block]:
    """The ```bash / ```sh / ```console blocks of one Markdown file, with the markers right before them, and
    the blocks without a language that hold commands (which :func:`test_every_command_states_its_outcome`
    refuses)."""
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
        if lang in RUN or (lang == "" and any(COMMAND.match(line) for line in body)):
            blocks.append(Block(path.name, start, _commands(lang, body), markers, lang))
        elif any(kind == "file" for kind, _ in markers):
            blocks.append(Block(path.name, start, [], markers, lang, "\n".join(body) + "\n"))
        lang, markers = None, []
    return blocks


def _commands(lang: str, body: list[str]) -> list[str]:
    if lang == "console" or lang == "":
        return [line[2:].strip() for line in body if line.startswith("$ ")]
    text = "\n".join(body).replace("\\\n", " ")
    return [line.strip() for line in text.splitlines() if line.strip() and not line.strip().startswith("#")]


def documents() -> list[Path]:
    skip = TESTED_ELSEWHERE
    return [REPO / "README.md"] + sorted(p for p in (REPO / "docs").glob("*.md") if p.name not in skip)


def _params():
    out = []
    for path in documents():
        if path.name in FROM_ANY_DIRECTORY:
            continue
        commands = [c for b in doc_blocks(path) for _, c in b.runnable()]
        if commands:
            slow = any(k in c for c in commands for k in SLOW)
            out.append(pytest.param(path, marks=[pytest.mark.slow] if slow else [], id=path.name))
    return out


# ----------------------------------------------------------------------------------------------
# fast checks
# ----------------------------------------------------------------------------------------------
def test_markers_and_blocks_are_well_formed():
    for path in documents():
        for block in doc_blocks(path):
            where = f"{path.name}:{block.line}"
            block.plan()  # a stale 'sub' fails here
            for kind, arg in block.markers:
                quoted = QUOTED.findall(arg)
                assert len(quoted) >= {"sub": 2, "expect": 2, "skip": 0, "busy": 0}.get(kind, 1), (where, arg)
                assert kind not in ("skip", "drop", "busy") or QUOTED.sub("", arg).strip(), (
                    f"{where}: {kind} needs a reason"
                )
                if kind == "expect":
                    assert any(quoted[0] in c for c in block.commands), f"{where}: expect '{quoted[0]}' matches nothing"
                    assert block.expectations(quoted[0])[0][0] in EXPECTATIONS, f"{where}: unknown check '{quoted[1]}'"


def test_every_command_states_its_outcome():
    """Each command the docs test runs has an ``expect`` marker, or is not run for a stated reason (``skip``,
    ``drop``, a page in TESTED_ELSEWHERE).  A background job (``&``) is checked by its ``kill -INT %N``:
    started, then exit 0 (and the ``expect`` markers of that ``kill`` line, on the job's output)."""
    unchecked = []
    for path in documents():
        for block in doc_blocks(path):
            if not block.lang:
                unchecked.append(
                    f"{path.name}:{block.line}: a command block needs a language: ```bash (run) or ```text"
                )
            for original, cmd in block.plan():
                if not (cmd.endswith("&") or JOB_STOP.fullmatch(cmd) or block.expectations(original)):
                    unchecked.append(f"{path.name}:{block.line}: {original}")
    assert not unchecked, "commands without an 'expect' marker or a reason not to run them:\n" + "\n".join(unchecked)


def test_every_benchmark_the_docs_name_is_listed_with_a_reason():
    named = set()
    for path in [REPO / "README.md", *(REPO / "docs").glob("*.md")]:
        named |= set(re.findall(r"python benchmarks/(\w+\.py)", path.read_text()))
    assert named and named <= set(BENCHMARKS), f"benchmarks without a reason in BENCHMARKS: {named - set(BENCHMARKS)}"
    assert all((REPO / "benchmarks" / name).is_file() for name in named), named
    for reason in BENCHMARKS.values():
        assert all((REPO / f).is_file() for f in re.findall(r"tests/\S+\.py", reason)), reason


def test_graph_files_named_in_doc_commands_validate():
    graphs = set()
    for path in documents() + [REPO / "docs" / d for d in TESTED_ELSEWHERE]:
        for block in filter(Block.available, doc_blocks(path)):
            for cmd in block.commands:
                graphs |= {w for w in shlex.split(cmd.rstrip("&")) if w.endswith(".yaml") and "/" in w}
    graphs = {g for g in graphs if (REPO / g).is_file()}  # not files the commands write
    graphs = {g for g in graphs if "nodes" in (yaml.safe_load((REPO / g).read_text()) or {})}  # not training configs
    assert len(graphs) >= 5, graphs
    for g in sorted(graphs):
        load_graph(REPO / g)


def test_foxglove_layout_topics_are_published_by_the_flagship():
    layout = json.loads((REPO / "configs" / "foxglove_layout.json").read_text())
    graph = load_graph(REPO / "configs" / "demo.yaml")
    text = json.dumps(layout["configById"])
    topics = set(re.findall(r"demo/(\w+)/(\w+)", text))
    assert topics
    assert not re.search(r"(?<!/)handflow/demo/", text), "layout topics are ROS 2 names: /handflow/demo/..."
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


class Job:
    """A background command (``CMD &``), its output read as it comes so that its graph's start can be waited for."""

    STARTED = ("all nodes ready", "the other nodes start without")  # the launcher's start-up lines (runtime/startup.py)

    def __init__(self, cmd: str, cwd: Path) -> None:
        self.proc = subprocess.Popen(
            ["bash", "-c", f"exec {cmd}"], cwd=cwd, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        self.since = time.time()
        self._started = threading.Event()
        self._out: list[str] = []
        self._err: list[str] = []
        self._readers = [
            threading.Thread(target=self._read, args=(stream, lines), daemon=True)
            for stream, lines in ((self.proc.stdout, self._out), (self.proc.stderr, self._err))
        ]
        for reader in self._readers:
            reader.start()

    def _read(self, stream, lines: list[str]) -> None:
        for line in stream:
            lines.append(line)
            if any(text in line for text in self.STARTED):
                self._started.set()
        self._started.set()  # the command ended: nothing more to wait for

    def wait_started(self, where: str, timeout: float = 60.0) -> None:
        """Until the launcher says its nodes are up (an event, not a fixed time)."""
        assert self._started.wait(timeout), f"{where}: no start-up line within {timeout:.0f}s\n{''.join(self._err)}"
        assert self.proc.poll() is None, f"{where}: ended at once (exit {self.proc.returncode})\n{''.join(self._err)}"

    def stop(self, sig: int = signal.SIGINT) -> tuple[str, str]:
        """Send ``sig``, wait for the command's end and return its whole stdout and stderr."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        self.proc.wait(timeout=60)
        for reader in self._readers:
            reader.join(timeout=10)
        return "".join(self._out), "".join(self._err)


@pytest.mark.parametrize("doc", _params())
def test_documented_commands_run(doc, workspace):
    run_page(doc, workspace)


def run_page(doc: Path, workspace: Path) -> None:
    """Run a page's commands in order in ``workspace``, checking each one's stated outcome."""
    jobs: list[Job | None] = []  # by job number - 1, as bash numbers them (None: stopped)
    shipped = set(workspace.glob("configs/*.yaml"))  # the installed package's graphs: `handflow run NAME`
    try:
        for block in doc_blocks(doc):
            for kind, arg in block.markers:
                if kind == "file":
                    target = workspace / QUOTED.findall(arg)[0]
                    target.parent.mkdir(parents=True, exist_ok=True)
                    target.write_text(block.text)
            busy = cpu_hog() if any(kind == "busy" for kind, _ in block.markers) else nullcontext()
            with busy:
                _run_block(doc, block, workspace, jobs)
    finally:
        for job in jobs:
            if job is not None:
                job.stop(signal.SIGKILL)
    added = sorted(p.name for p in set(workspace.glob("configs/*.yaml")) - shipped)
    assert not added, (
        f"{doc.name} writes graph(s) {added} into the package, listed as shipped; write to the current directory"
    )


def _run_block(doc: Path, block: Block, workspace: Path, jobs: list[Job | None]) -> None:
    """Run one block's commands in ``workspace``: background jobs into ``jobs``, checking each outcome."""
    for original, cmd in block.runnable():
        where = f"{doc.name}:{block.line}: {cmd}"
        if kill := JOB_STOP.fullmatch(cmd):
            job = jobs[int(kill.group(1)) - 1]
            out, err = job.stop()
            _check(block, original, Outcome(workspace, out, err, job.proc.returncode, job.since), where)
            jobs[int(kill.group(1)) - 1] = None
            while jobs and jobs[-1] is None:  # a new job is numbered after the highest one still running
                jobs.pop()
        elif cmd.endswith("&"):
            jobs.append(Job(cmd[:-1], workspace))
            jobs[-1].wait_started(where)
        else:
            since = time.time()
            proc = subprocess.run(["bash", "-c", cmd], cwd=workspace, capture_output=True, text=True, timeout=300)
            _check(block, original, Outcome(workspace, proc.stdout, proc.stderr, proc.returncode, since), where)


def _check(block: Block, original: str, outcome: Outcome, where: str) -> None:
    """The command's exit code (0 unless an ``exit`` check says otherwise), then its ``expect`` checks."""
    checks = block.expectations(original)
    code = next((int(args[0]) for name, *args in checks if name == "exit"), 0)
    assert outcome.code == code, f"{where}: exit {outcome.code}\n{outcome.stdout[-2000:]}\n{outcome.stderr[-4000:]}"
    for name, *args in checks:
        try:
            EXPECTATIONS[name](outcome, *args)
        except AssertionError as e:
            raise AssertionError(f"{where}: expect {name} {' '.join(args)}: {e}") from None


@pytest.mark.slow
def test_the_training_tutorial_works_from_an_empty_directory(workspace):
    """docs/tutorial_training.md from a directory holding nothing of the checkout writes what it says."""
    elsewhere = workspace.parent / "elsewhere"
    elsewhere.mkdir()
    run_page(REPO / "docs" / "tutorial_training.md", elsewhere)
    out = elsewhere / "out"
    assert sorted(p.name for p in (out / "my_plots").iterdir()) == ["latents.png", "manifold.png", "objective.png"]
    from handflow.plugins.manifold import StructuredUKR

    model = StructuredUKR.load(out / "my_manifold.npz")
    assert model.latents_.shape[1] == 1 and model.Y_.shape[1] == 24  # one latent time, 24 ShadowHand joints
    # the good fit the page shows: a low objective, every demonstration climbing once round the
    # period π, never falling back more than 0.05 rad (the page's "runs backwards" is the bad fit)
    assert model.objective_ <= 0.2, model.objective_
    for seq in np.unique(model.sequence_ids_):
        latent = np.unwrap(model.latents_[model.sequence_ids_ == seq, 0], period=np.pi)
        assert (latent - np.maximum.accumulate(latent)).min() >= -0.05, f"demonstration {seq} runs backwards"
        assert latent[-1] - latent[0] >= 0.9 * np.pi, f"demonstration {seq} climbs {latent[-1] - latent[0]:.2f} rad"


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_the_gestures_tutorial_works_from_an_empty_directory(workspace):
    """docs/tutorial_gestures.md from an empty directory: the dataset's counts, the estimate, and labels
    that match the gestures the emulated hand performed on a fresh session (docs/benchmarks.md).  The page's
    ``sub`` markers shorten the cues, the rests and the live gestures (every step runs)."""
    from handflow.framework.files.labels import recognition_shares
    from handflow.plugins.segmenter.datasets import load_recordings

    page = REPO / "docs" / "tutorial_gestures.md"
    elsewhere = workspace.parent / "elsewhere"
    elsewhere.mkdir()
    run_page(page, elsewhere)
    out = elsewhere / "out"
    data = load_recordings(out / "gestures.npz")
    assert len(data.recordings) == 5 and data.known_classes == ["grasp", "pinch", "wave"]
    collect = next(c for b in doc_blocks(page) for _, c in b.runnable() if c.startswith("handflow collect"))
    cue_s = float(re.search(r"--cue-s (\S+)", collect).group(1)) if "--cue-s" in collect else 4.0
    for rec in data.recordings:  # each recording is one round: every class once, cue_s seconds at 50 Hz
        counts = np.bincount(rec.y[rec.y >= 0], minlength=4)
        assert all(0.8 * 50 * cue_s <= n <= 1.25 * 50 * cue_s for n in counts[:3]), (cue_s, counts)
    check = json.loads((out / "check.json").read_text())
    assert check["protocol"]["name"] == "preview" and check["protocol"]["optimistic"] is True
    estimate = check["methods"]["ukr_clm"]
    assert estimate["open_set_accuracy"] >= 0.8 and estimate["known_accuracy"] >= 0.8, estimate
    chosen = estimate["folds"][0]["selected"]  # the preview's one choice, which the live segmenter runs at
    assert json.loads((elsewhere / "models" / "classes.json").read_text())["provenance"]["history"] == chosen["history"]
    assert sorted(json.loads((elsewhere / "models" / "classes.json").read_text())["classes"]) == [
        "grasp",
        "pinch",
        "wave",
    ]
    live = recognition_shares(out / "live.mcap", "glove/performed", "segmenter/labels", revisions=False)
    replayed = recognition_shares(out / "replayed.mcap", "glove/performed", "segmenter/labels", out / "live.mcap")
    for gesture in ("grasp", "pinch", "wave"):
        assert live[gesture]["right"] >= 0.7, live
        assert replayed[gesture]["right"] >= 0.9, replayed
    assert live["turn"]["unknown"] >= 0.5 and replayed["turn"]["unknown"] >= 0.5, (live, replayed)


def test_the_loopback_lsl_setup_shown_in_lsl_md_is_the_shipped_file():
    """docs/lsl.md shows docs/examples/lsl_api_loopback.cfg, which liblsl reads through LSLAPICFG."""
    shown = re.search(r"```ini\n(.*?)```", (REPO / "docs" / "lsl.md").read_text(), re.S).group(1)
    page, shipped = configparser.ConfigParser(), configparser.ConfigParser()
    page.optionxform = shipped.optionxform = str  # liblsl's keys are case-sensitive
    page.read_string(textwrap.dedent(shown))
    shipped.read(REPO / "docs" / "examples" / "lsl_api_loopback.cfg")
    assert {s: dict(page[s]) for s in page.sections()} == {s: dict(shipped[s]) for s in shipped.sections()}
    assert shipped["multicast"]["ResolveScope"] == "machine" and "127.0.0.1" in shipped["lab"]["KnownPeers"]
