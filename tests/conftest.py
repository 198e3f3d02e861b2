"""Shared pytest fixtures: running the ``handflow`` CLI as a real subprocess, or one command in-process."""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


DURATIONS = Path(__file__).with_name("slow_durations.json")  # test id → seconds in a measured slow-tier run


def pytest_collection_modifyitems(config, items):
    """Longest first (docs/testing.md): modules by the seconds their tests took in a measured run
    (``tests/slow_durations.json``), the longest tests first within a module, tests not listed after the
    listed ones in their collected order.  pytest-xdist hands the tests out in this order, so the workers
    start the long ones at once and finish together, rather than one running a long test alone at the end;
    a module's tests stay together, so its module-scoped fixtures are set up once per worker."""
    known = json.loads(DURATIONS.read_text()) if DURATIONS.exists() else {}
    if not any(item.nodeid in known for item in items):
        return
    module_seconds: dict[str, float] = {}
    first: dict[str, int] = {}
    for i, item in enumerate(items):
        module = _module(item)
        module_seconds[module] = module_seconds.get(module, 0.0) + known.get(item.nodeid, 0.0)
        first.setdefault(module, i)
    order = {id(item): i for i, item in enumerate(items)}
    items.sort(
        key=lambda item: (
            -module_seconds[_module(item)],
            first[_module(item)],
            -known.get(item.nodeid, 0.0),
            order[id(item)],
        )
    )


def _module(item) -> str:
    """The test file of a collected test (its node id up to the first ``::``)."""
    return item.nodeid.split("::")[0]


@pytest.hookimpl(trylast=True)  # after pytest's temporary-folder factory is configured
def pytest_configure(config):
    """Each pytest process (an xdist worker, or the only one) gets a private ``$TMPDIR`` — so its own iceoryx2
    namespace in ``/dev/shm`` and its own launcher state folders — and a private run folder
    (``$HANDFLOW_RUN_DIR``), inherited by every process its tests start: tests running side by side never
    see each other's graphs (docs/testing.md).  A test may narrow them further (its ``tmp_path``)."""
    config._tmp_path_factory.getbasetemp()
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    private = Path(tempfile.mkdtemp(prefix=f"hf{worker}-", dir="/tmp"))  # short: iceoryx2's socket paths
    config._handflow_tmp = private
    os.environ["TMPDIR"] = str(private)
    os.environ["HANDFLOW_RUN_DIR"] = str(private / "runs")
    tempfile.tempdir = None  # gettempdir() reads $TMPDIR again
    slow_tier = "not slow" not in (config.option.markexpr or "")  # the slow tier, or both tiers
    if slow_tier and getattr(config.option, "maxschedchunk", False) is None:  # pytest-xdist, no chunk size given
        # hand tests out one at a time, in the longest-first order of pytest_collection_modifyitems; by default
        # each worker's first batch is a run of consecutive tests, the longest all on one worker.  The default
        # tier (no test there is listed) keeps xdist's batches, which keep a module's tests on fewer workers.
        config.option.maxschedchunk = 1


def pytest_unconfigure(config):
    private = getattr(config, "_handflow_tmp", None)
    if private is None:
        return
    from handflow.framework.network import local_transport

    local_transport.remove_leftovers()  # this process's iceoryx2 namespace: files of nodes that were killed
    shutil.rmtree(private, ignore_errors=True)


def handflow(*args: str, timeout: float = 120, check: bool = False, **kw) -> subprocess.CompletedProcess:
    """Run ``handflow ARGS`` in a fresh interpreter; returns the completed process (text output)."""
    proc = subprocess.run(
        [sys.executable, "-m", "handflow.framework.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=kw.pop("cwd", REPO),
        **kw,
    )
    if check and proc.returncode != 0:
        raise AssertionError(f"handflow {' '.join(args)} failed ({proc.returncode}):\n{proc.stdout}\n{proc.stderr}")
    return proc


@contextmanager
def cpu_hog() -> Iterator[None]:
    """A busy machine: a process spinning on one core while the block runs."""
    hog = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        yield
    finally:
        hog.kill()
        hog.wait()


def run_command(register, argv: list[str]):
    """Run one command in-process: ``register`` adds its arguments to a parser, ``argv`` is parsed."""
    parser = argparse.ArgumentParser()
    register(parser)
    args = parser.parse_args(argv)
    return args.func(args)


@pytest.fixture
def run_handflow():
    return handflow


def processes_of(folder: Path) -> list[int]:
    """Live processes (zombies aside) that a test started in ``folder``: its path in their command line (a
    graph file there) or their working directory below it.  Empty where there is no ``/proc``."""
    found = []
    for entry in Path("/proc").glob("[0-9]*"):
        if int(entry.name) == os.getpid():
            continue
        try:
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            cwd = os.readlink(entry / "cwd") if str(folder) not in command else str(folder)
        except (OSError, IndexError):  # gone meanwhile, or not ours to look at
            continue
        if state != "Z" and (str(folder) in command or Path(cwd).is_relative_to(folder)):
            found.append(int(entry.name))
    return found


def kill_processes_of(folder: Path) -> list[int]:
    """SIGKILL what :func:`processes_of` finds; returns their pids."""
    pids = processes_of(folder)
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    return pids


@pytest.fixture(autouse=True)
def _no_process_left(request):
    """A test that fails or times out (pytest-timeout) leaves no launcher, zygote or node process running: what
    it started in its ``tmp_path`` is killed at its end, with a warning naming them."""
    folder = request.getfixturevalue("tmp_path") if "tmp_path" in request.fixturenames else None
    yield
    if folder is not None and (left := kill_processes_of(folder)):
        warnings.warn(f"{request.node.nodeid} left processes running; killed: {left}", stacklevel=1)
