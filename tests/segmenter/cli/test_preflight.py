"""Evaluation preflight (docs/segmentation.md, "Methods and their extras"): the extras of the
methods an evaluation runs are checked before anything is computed.

The commands run in a subprocess where the extras' modules are hidden the way a missing install
hides them (``sys.modules[name] = None``: ``import`` and ``find_spec`` both fail), so the tests
hold in a venv with every extra and in a core-only one alike."""

import json
import subprocess
import sys
from importlib.metadata import metadata
from pathlib import Path

import numpy as np
import pytest

from handflow.plugins.segmenter.evaluation import DEFAULT_METHODS, REGISTRY, methods_to_run
from tests.segmenter.datasets.test_trajectories import write_csv_dataset

EXTRAS = {"hmmlearn": "hmm", "aeon": "minirocket"}
HIDDEN = ("hmmlearn", "aeon")
WITHOUT = (
    "import sys; sys.modules.update(dict.fromkeys(sys.argv.pop(1).split(',')));"
    "from handflow.framework.cli import main; sys.exit(main())"
)


def handflow_without(modules, *argv: str, timeout: float = 600) -> subprocess.CompletedProcess:
    """``handflow ARGV`` with ``modules`` not importable."""
    return subprocess.run(
        [sys.executable, "-c", WITHOUT, ",".join(modules), *argv], capture_output=True, text=True, timeout=timeout
    )


@pytest.fixture(scope="module")
def recordings(tmp_path_factory) -> Path:
    """Three recordings of two classes, 30 noisy frames a segment (the least leave-one-out takes)."""
    rng, t = np.random.default_rng(0), np.linspace(0, 2 * np.pi, 30)
    shapes = (np.c_[np.sin(t), np.cos(t)], np.c_[np.sin(2 * t), -np.abs(np.cos(t))])
    arrays = {"class_names": np.array(["a", "b"])}
    for k in range(3):
        order = [k % 2, 1 - k % 2] * 2
        arrays[f"X_r{k}"] = np.vstack([shapes[c] for c in order]) + rng.normal(0, 0.02, (120, 2))
        arrays[f"y_r{k}"] = np.repeat(order, 30)
    path = tmp_path_factory.mktemp("rec") / "tiny.npz"
    np.savez(path, **arrays)
    return path


def test_every_method_declares_the_extras_of_its_scorer():
    needs = {name: set(m.requires.values()) for name, m in REGISTRY.items() if m.requires}
    assert needs == {
        "hmm": {"hmm"},
        "minirocket": {"minirocket"},
        "clm_minirocket": {"minirocket"},
        "clm_minirocket_novelty": {"minirocket"},
    }
    extras = metadata("handflow").get_all("Provides-Extra")
    assert all(extra in extras for m in REGISTRY.values() for extra in m.requires.values())


def test_installed_extras_are_not_skipped():
    installed = [name for name in DEFAULT_METHODS if all(_importable(mod) for mod in REGISTRY[name].requires)]
    said: list[str] = []
    methods, skipped = methods_to_run(None, DEFAULT_METHODS, REGISTRY, said.append)
    assert list(methods) == installed and set(skipped) == set(DEFAULT_METHODS) - set(installed)
    assert len(said) == len(skipped)
    assert methods_to_run("dtw_1nn,ukr_clm", DEFAULT_METHODS, REGISTRY, said.append) == (("dtw_1nn", "ukr_clm"), {})
    with pytest.raises(ValueError, match=r"unknown method\(s\) \['nope'\]"):
        methods_to_run("dtw_1nn,nope", DEFAULT_METHODS, REGISTRY, said.append)


def _importable(module: str) -> bool:
    try:
        __import__(module)
    except ImportError:
        return False
    return True


@pytest.mark.slow
def test_without_extras_the_core_methods_run_and_the_skipped_ones_are_named(recordings):
    one_view = ("--normalise", "training", "--derived", "none")  # the methods run and are skipped alike on any view
    done = handflow_without(HIDDEN, "evaluate", "segmentation", str(recordings), "--quick", "--json", *one_view)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    optional = {name for name in DEFAULT_METHODS if REGISTRY[name].requires}
    assert optional == {"hmm", "minirocket", "clm_minirocket"}
    assert set(result["methods"]) == set(DEFAULT_METHODS) - optional
    assert set(result["skipped_methods"]) == optional
    for name in optional:
        extra = EXTRAS[next(iter(REGISTRY[name].requires))]
        assert f"pip install 'handflow[{extra}]'" in result["skipped_methods"][name]
        assert f"skipping {name}: it needs" in done.stderr  # in the progress output too
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize(
    ("dataset", "methods", "extra"),
    [
        ("recordings", "hmm", "hmm"),
        ("recordings", "dtw_1nn,clm_minirocket", "minirocket"),
        ("trajectories", "hmm", "hmm"),
    ],
)
def test_a_method_named_without_its_extra_is_an_error_at_once(request, tmp_path, dataset, methods, extra):
    if dataset == "trajectories":
        path = write_csv_dataset(tmp_path / "letters", request.getfixturevalue("synthetic"))
    else:
        path = request.getfixturevalue("recordings")
    done = handflow_without(HIDDEN, "evaluate", "segmentation", str(path), "--methods", methods, timeout=60)
    assert done.returncode == 2, done.stderr
    assert f"pip install 'handflow[{extra}]'" in done.stderr and "Traceback" not in done.stderr
    assert "fold" not in done.stderr and "training" not in done.stderr  # nothing was computed


def test_fit_scorer_without_its_extra_is_an_error_before_reading_the_data(tmp_path):
    out = tmp_path / "s.npz"
    done = handflow_without(HIDDEN, "fit-scorer", str(tmp_path / "missing.npz"), "--out", str(out), timeout=60)
    assert done.returncode == 2 and not out.exists()
    assert "--source minirocket needs aeon" in done.stderr and "pip install 'handflow[minirocket]'" in done.stderr
    assert "missing.npz" not in done.stderr  # checked before the (missing) data
