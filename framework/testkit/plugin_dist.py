"""A plugin registered as pip would register it: a ``*.dist-info`` folder with its entry points, on
``PYTHONPATH`` (docs/pipelines.md, "Writing a plugin")."""

from __future__ import annotations

import os
import sys
from pathlib import Path


def register_plugins(folder: Path, dist: str, entries: dict[str, str]) -> dict[str, str]:
    """Register plugin name → ``module:Class`` for the modules in ``folder``; returns the environment
    under which ``handflow`` finds them."""
    info = folder / f"{dist}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n")
    lines = "".join(f"{name} = {target}\n" for name, target in entries.items())
    (info / "entry_points.txt").write_text("[handflow.plugins]\n" + lines)
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(folder), *sys.path]))
