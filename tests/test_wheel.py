"""The wheel works anywhere: built from the checkout, installed into a fresh venv, run from a directory
outside the checkout (README "Set-up"; docs/architecture.md).

The venv sees the dependencies installed for the interpreter running the test (a ``.pth`` file lists its
site-packages, so this works from the system interpreter and from inside a venv alike) and needs no
network; handflow itself comes from the wheel, which the test checks.
"""

from __future__ import annotations

import site
import subprocess
import sys
import venv
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.slow


def _run(cmd, cwd, timeout=300):
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, f"{cmd}\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


def _venv_seeing_this_interpreters_packages(root: Path) -> Path:
    """A venv whose path ends with this interpreter's site-packages: ``system_site_packages`` alone would
    show the base interpreter's packages, not those of the venv the tests run in (issue #37).  Plain path
    lines process no ``.pth`` file there, so an editable install of the checkout stays invisible."""
    venv.EnvBuilder(with_pip=False).create(root)
    python = root / "bin" / "python"
    purelib = subprocess.run(
        [python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"], capture_output=True, text=True
    ).stdout.strip()
    dirs = [*site.getsitepackages(), *([site.getusersitepackages()] if site.ENABLE_USER_SITE else [])]
    Path(purelib, "outer_site_packages.pth").write_text("\n".join(dirs) + "\n")
    return python


def test_the_wheel_runs_the_demo_validate_plugins_and_a_train_outside_the_checkout(tmp_path):
    dist = tmp_path / "dist"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-w", dist, REPO], tmp_path)
    (wheel,) = dist.glob("handflow-*.whl")
    python = _venv_seeing_this_interpreters_packages(tmp_path / "venv")
    _run([sys.executable, "-m", "pip", "--python", python, "install", "-q", "--no-deps", wheel], tmp_path)
    work = tmp_path / "elsewhere"
    work.mkdir()
    where = _run([python, "-c", "import handflow.framework as f; print(f.__file__)"], work)
    assert where.startswith(str(tmp_path / "venv")), where  # the wheel's copy, not the checkout
    handflow = [python, "-m", "handflow.framework.cli"]
    assert "segmenter.online_clm" in _run([*handflow, "plugins"], work)
    assert "valid graph 'demo'" in _run([*handflow, "validate", "demo"], work)
    _run([*handflow, "run", "demo", "--duration", "3", "--record", "demo.mcap"], work, timeout=240)
    assert (work / "demo.mcap").stat().st_size > 0
    config = _run([python, "-c", "from handflow.framework.files.resources import shipped; print(shipped('train', 'toy_cylinder.yaml'))"], work).strip()  # fmt: skip
    _run([*handflow, "train", config, "--out", "toy.npz", "--steps", "5", "--quiet"], work)
    assert (work / "toy.npz").is_file() and not list(work.rglob("*.yaml"))
