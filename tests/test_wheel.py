"""The wheel works anywhere: built from the checkout, installed into a fresh venv, run from a directory
outside the checkout (README "Set-up"; docs/architecture.md).

The venv sees this machine's installed dependencies (``--system-site-packages``) so the test needs no
network; handflow itself comes from the wheel, which the test checks.
"""

from __future__ import annotations

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


def test_the_wheel_runs_the_demo_validate_plugins_and_a_train_outside_the_checkout(tmp_path):
    dist = tmp_path / "dist"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-w", dist, REPO], tmp_path)
    (wheel,) = dist.glob("handflow-*.whl")
    venv.EnvBuilder(system_site_packages=True, with_pip=False).create(tmp_path / "venv")
    python = tmp_path / "venv" / "bin" / "python"
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
