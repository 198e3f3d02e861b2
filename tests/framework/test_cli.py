"""The ``handflow`` command itself (framework/cli.py)."""

from __future__ import annotations

import importlib.metadata
import re


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
