"""The construction and learning modes of ``handflow train`` on real demonstration recordings."""

import argparse

import numpy as np
import pytest

from handflow.plugins.demo.demonstrations import record_cap
from handflow.plugins.manifold.cli import run_train, train_mode_handler
from handflow.plugins.manifold.validation import InvalidInputError
from handflow.plugins.manipulation import ManipulationManifold
from handflow.plugins.manipulation.training import run_manipulation_training


@pytest.fixture(scope="module")
def cap_demo(tmp_path_factory):
    path = tmp_path_factory.mktemp("demo") / "cap.mcap"
    record_cap(path, radii=(0.015, 0.025), sequences=2, seed=3)
    return path


def _args(config, out, steps=None):
    return argparse.Namespace(config=config, out=out, plot=None, steps=steps, quiet=True)


def test_construction_mode_builds_a_named_time_radius_manifold(tmp_path, cap_demo):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"mode: construction\ndata: {{demo: {cap_demo}}}\nconstruction: {{n_steps: 20}}\n")
    assert train_mode_handler(cfg) is run_manipulation_training  # found by entry point
    assert run_train(_args(cfg, tmp_path / "m.npz")) == 0  # `handflow train` dispatches
    m = ManipulationManifold.load(tmp_path / "m.npz")
    assert m.kind == "constructed" and m.hand == "shadow" and len(m.joint_names) == 24
    assert m.latent_names == ["time", "radius_cm"] and not m.periodic
    assert sorted(np.unique(m.model.latents_[:, 1])) == [1.5, 2.5]
    assert m.model.provenance_["mode"] == "construction"


def test_learning_mode_reports_the_radius_order(tmp_path, cap_demo):
    cfg = tmp_path / "l.yaml"
    cfg.write_text(
        f"mode: learning\ndata: {{demo: {cap_demo}}}\nmodel:\n  latent:\n"
        "    - {kernel: periodic, beta: 10, time: true}\n    - {kernel: gaussian, beta: 4}\n"
        "training: {n_steps: 30, isomap_neighbors: [10]}\n"
    )
    assert run_manipulation_training(_args(cfg, tmp_path / "l.npz")) == 0
    m = ManipulationManifold.load(tmp_path / "l.npz")
    assert m.kind == "learned" and m.periodic
    prov = m.model.provenance_
    assert -1.0 <= prov["spearman"] <= 1.0 and prov["separation"] > 0
    assert len(prov["sequence_means"]) == 4


def test_bad_configs_exit_2_with_what_to_change(tmp_path, cap_demo, capsys):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(f"mode: construction\ndata: {{demo: {cap_demo}}}\nconstruction: {{time_beta: -1}}\n")
    assert run_manipulation_training(_args(cfg, tmp_path / "m.npz")) == 2
    assert "construction.time_beta" in capsys.readouterr().err
    cfg.write_text(f"mode: construction\ndata: {{demo: {tmp_path / 'missing.mcap'}}}\n")
    assert run_manipulation_training(_args(cfg, tmp_path / "m.npz")) == 2
    assert "handflow demo-record" in capsys.readouterr().err
    cfg.write_text("model: {}\n")
    assert train_mode_handler(cfg) is None  # a plain UKR config: no mode
    cfg.write_text("mode: sculpting\n")
    with pytest.raises(InvalidInputError, match="construction, learning"):
        train_mode_handler(cfg)
