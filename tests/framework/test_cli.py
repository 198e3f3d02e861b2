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
