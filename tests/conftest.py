"""Shared pytest fixtures: running the ``handflow`` CLI as a real subprocess, or one command in-process."""

from __future__ import annotations

import argparse
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


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
