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


def test_every_parameter_and_config_model_derives_the_one_strict_base():
    """Node Params, graph settings, training configs, profiles and calibrations reject unknown keys alike."""
    import importlib
    import pkgutil
    import warnings

    from pydantic import BaseModel

    import handflow.framework
    import handflow.plugins
    from handflow.framework.files.params import StrictModel

    loose = []
    for package in (handflow.framework, handflow.plugins):
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # renamed plugins' aliases warn on import
                module = importlib.import_module(info.name)
            for obj in vars(module).values():
                if (
                    isinstance(obj, type)
                    and issubclass(obj, BaseModel)
                    and obj.__module__ == module.__name__
                    and not issubclass(obj, StrictModel)
                ):
                    loose.append(f"{module.__name__}.{obj.__qualname__}")
                for inner in vars(obj).values() if isinstance(obj, type) else ():
                    if isinstance(inner, type) and issubclass(inner, BaseModel) and not issubclass(inner, StrictModel):
                        loose.append(f"{module.__name__}.{inner.__qualname__}")
    assert not sorted(set(loose)), f"models that accept unknown keys (derive StrictModel): {sorted(set(loose))}"
