"""The layering of docs/architecture.md holds, and the package list covers every source folder."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
tomllib = pytest.importorskip("tomllib")  # Python >= 3.11


@pytest.mark.skipif(
    shutil.which("lint-imports") is None, reason="import-linter not installed (pip install -e '.[test]')"
)
def test_import_linter_contracts_are_kept():
    proc = subprocess.run(["lint-imports"], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_every_source_package_is_declared_under_the_handflow_name():
    declared = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {"handflow.configs", "handflow.recordings"}
    for folder in ("framework", "plugins"):
        for init in (REPO / folder).rglob("__init__.py"):
            found.add(".".join(("handflow", folder, *init.parent.relative_to(REPO / folder).parts)))
    assert declared == found


def test_old_top_level_names_are_not_importable_from_elsewhere(tmp_path):
    code = "import importlib.util as u; print(u.find_spec('framework'), u.find_spec('plugins'))"
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True).stdout
    assert out.strip() == "None None"


@pytest.mark.skipif(shutil.which("ruff") is None, reason="ruff not installed (pip install -e '.[test]')")
@pytest.mark.parametrize("args", [["check", "."], ["format", "--check", "."]], ids=["lint", "format"])
def test_ruff_keeps_the_tree_clean(args):
    proc = subprocess.run(["ruff", *args], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
