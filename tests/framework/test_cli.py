"""The ``handflow`` command itself (framework/cli.py)."""

from __future__ import annotations

import importlib.metadata
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from handflow.framework import cli

REPO = Path(__file__).resolve().parents[2]


def test_version_prints_the_installed_distributions_version(run_handflow):
    proc = run_handflow("--version", timeout=60)
    assert proc.returncode == 0, proc.stderr
    version = importlib.metadata.version("handflow")
    assert re.fullmatch(r"\d+\.\d+\.\d+\S*", version), version
    assert proc.stdout.strip() == f"handflow {version}"


def test_a_command_whose_plugin_fails_to_import_says_why_whatever_its_arguments(monkeypatch, capsys):
    from handflow.framework import cli

    broken = importlib.metadata.EntryPoint(
        name="evaluate.broken", value="handflow_no_such_module:register", group="handflow.commands"
    )
    monkeypatch.setattr(cli, "command_entries", lambda: [broken])
    assert cli.main(["evaluate", "broken", "data.npz", "--quick", "--json"]) == 1
    err = capsys.readouterr().err
    assert "handflow evaluate broken is unavailable: ModuleNotFoundError" in err
    assert "handflow_no_such_module" in err


def _listed(parser) -> dict[str, str | None]:
    """Command (or group) name → its help line, as ``handflow [GROUP] --help`` lists them."""
    import argparse

    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {a.dest: a.help for a in sub._choices_actions}


def test_every_command_and_group_has_a_one_line_description_in_help(run_handflow):
    from handflow.framework import cli
    from handflow.framework.registry import command_entries

    top = _listed(cli.build_parser([]))
    names = {ep.name.split(".")[0] for ep in command_entries()}
    assert set(top) == names and {"certs", "evaluate", "param", "compare"} <= names
    for group in ("certs", "evaluate"):
        sub = _listed(cli.build_parser([group])._subparsers._group_actions[0].choices[group])
        assert len(sub) >= 2 and all(sub.values()), (group, sub)
        assert all(name in top[group] for name in sub), top[group]  # the group's line names its commands
        top |= {f"{group} {name}": text for name, text in sub.items()}
    missing = [name for name, text in top.items() if not text or not text.strip()]
    assert not missing, f"no description: {missing}"
    assert not [name for name, text in top.items() if "see `handflow" in text]
    # the line read from the source without importing is the docstring the command registers with
    for ep in command_entries():
        if ep.value.startswith("handflow.framework."):
            assert cli.summary(ep) == ep.load().__doc__.strip().splitlines()[0], ep.name
    proc = run_handflow("--help", timeout=60)
    assert proc.returncode == 0 and "see `handflow" not in proc.stdout
    assert "Compare two recordings" in proc.stdout and "init: create a certificate authority" in proc.stdout


@pytest.mark.parametrize("args", [["inspect", "recordings/gestures.mcap"], ["plugins"]], ids=["inspect", "plugins"])
def test_a_command_whose_reader_goes_away_ends_quietly_with_141(args):
    """``handflow inspect F | head -1``: stdout's reader is gone before the command writes (the case that loses
    every race), so every write fails; the command ends with 128 + SIGPIPE and no traceback."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "handflow.framework.cli", *args],
            stdout=write_end,
            stderr=subprocess.PIPE,
            text=True,
            cwd=REPO,
            timeout=120,
        )
    finally:
        os.close(write_end)
    assert proc.returncode == 141, proc.stderr
    assert proc.stderr == ""  # no traceback, no "Exception ignored" at the interpreter's exit


def test_a_broken_pipe_that_is_not_stdout_is_not_hidden(monkeypatch):
    """Only stdout's reader going away is taken for ``| head``; any other broken pipe stays an error."""
    monkeypatch.setattr(cli, "_main", lambda argv: (_ for _ in ()).throw(BrokenPipeError("a socket")))
    with pytest.raises(BrokenPipeError, match="a socket"):
        cli.main(["plugins"])
