"""`handflow train` (register_train/run_train) and the data loaders."""

import argparse

import numpy as np
import pytest
import yaml

from handflow.framework.files.mcap_writer import McapWriter
from handflow.framework.messages import Array, JointState
from handflow.plugins.manifold import StructuredUKR, toy
from handflow.plugins.manifold.cli import register_train
from handflow.plugins.manifold.data import load_csv_dir, load_mcap, load_npz
from tests.manifold.ukr_helpers import closed_curves

RING = [{"kernel": "periodic", "beta": 12, "time": True}]


def run(*argv):
    parser = argparse.ArgumentParser()
    register_train(parser)
    args = parser.parse_args([str(a) for a in argv])
    return args.func(args)


def write_config(tmp_path, data, latent=RING, **training):
    cfg = {"data": data, "model": {"latent": latent}, "training": {"n_steps": 20, "isomap_neighbors": [10], **training}}
    path = tmp_path / "cfg.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def write_mcap(path, seqs, topic="handflow/rec/hand/joints", rate_hz=50.0, field="positions"):
    """A handflow recording: JointStates (``positions``) or Arrays (``data``) with a 1 s gap between sequences."""
    t = 0
    with McapWriter(path, flush_interval_s=None) as w:
        for seq in seqs:
            for row in seq:
                if field == "positions":
                    msg = JointState(names=["a", "b", "c"], positions=row)
                else:
                    msg = Array(data=row)
                w.write(topic, msg, log_time_ns=t)
                w.write("handflow/rec/other/data", Array(data=row), log_time_ns=t)
                t += int(1e9 / rate_hz)
            t += int(1e9)  # 1 s gap between demonstrations


@pytest.fixture
def csv_dir(tmp_path):
    return toy.write_csv_dir(tmp_path / "rings", heights=[0.0, 0.5, 1.0], random_state=1)


def test_train_csv_writes_model_and_plots(tmp_path, csv_dir, capsys):
    cfg = write_config(
        tmp_path, {"csv_dir": "rings", "time_column": "t"}, latent=[RING[0], {"kernel": "gaussian", "beta": 4}]
    )
    out, plots = tmp_path / "model.npz", tmp_path / "plots"
    assert run(cfg, "--out", out, "--plot", plots) == 0
    model = StructuredUKR.load(out)
    assert model.latents_.shape == (135, 2) and model.n_features_in_ == 3
    assert len(model.history_) == 21
    assert model.provenance_["sequences"] == ["ring_00", "ring_01", "ring_02"]
    assert sorted(p.name for p in plots.iterdir()) == ["latents.png", "manifold.png", "objective.png"]
    assert "objective" in capsys.readouterr().err


def test_train_npz_and_steps_override(tmp_path):
    np.savez(tmp_path / "seqs.npz", *closed_curves(noise=0.02))
    cfg = write_config(tmp_path, {"npz": "seqs.npz"}, init="equidistant")
    assert run(cfg, "--out", tmp_path / "m.npz", "--steps", "5", "--quiet") == 0
    assert len(StructuredUKR.load(tmp_path / "m.npz").history_) == 6


def test_train_mcap_time_ranges(tmp_path):
    seqs = closed_curves(n_seq=3, noise=0.02)
    write_mcap(tmp_path / "rec.mcap", seqs)
    got, names = load_mcap(tmp_path / "rec.mcap", "handflow/rec/hand/joints", "positions", [[0, 1.5], [2.0, 3.1]])
    np.testing.assert_allclose(got[0], seqs[0])
    np.testing.assert_allclose(got[1], seqs[1])
    whole, _ = load_mcap(tmp_path / "rec.mcap", "handflow/rec/hand/joints")
    assert len(whole) == 1 and len(whole[0]) == sum(map(len, seqs))
    cfg = write_config(
        tmp_path,
        {"mcap": "rec.mcap", "topic": "handflow/rec/hand/joints", "time_ranges": [[0, 1.5], [2.0, 3.1], [4.0, 5.2]]},
    )
    assert run(cfg, "--out", tmp_path / "m.npz", "--quiet") == 0


def test_mcap_data_field(tmp_path):
    seqs = closed_curves(n_seq=1)
    write_mcap(tmp_path / "rec.mcap", seqs, field="data")
    got, _ = load_mcap(tmp_path / "rec.mcap", "handflow/rec/hand/joints", field="data")
    np.testing.assert_allclose(got[0], seqs[0])


def test_ctrl_c_saves_best_model(tmp_path, csv_dir, monkeypatch):
    cfg = write_config(tmp_path, {"csv_dir": "rings", "time_column": "t"}, n_steps=50)
    from handflow.plugins.manifold.config import TrainingProgress

    real = TrainingProgress.__call__

    def interrupting(self, step, value):
        real(self, step, value)
        if step == 3:
            raise KeyboardInterrupt

    monkeypatch.setattr(TrainingProgress, "__call__", interrupting)
    assert run(cfg, "--out", tmp_path / "m.npz") == 0
    model = StructuredUKR.load(tmp_path / "m.npz")
    assert model.interrupted_ and len(model.history_) == 4


def test_csv_loader_sorts_by_time_and_selects_columns(tmp_path):
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "a.csv").write_text("t,x,y\n2,5,6\n1,3,4\n3,7,8\n")
    seqs, names = load_csv_dir(tmp_path / "d", time_column="t")
    np.testing.assert_array_equal(seqs[0], [[3, 4], [5, 6], [7, 8]])
    seqs, _ = load_csv_dir(tmp_path / "d", columns=["y"])
    assert seqs[0].shape == (3, 1)
    np.savez(tmp_path / "one.npz", a=np.arange(5.0))
    assert load_npz(tmp_path / "one.npz")[0][0].shape == (5, 1)


def bad_case(tmp_path, kind):
    d = tmp_path / "d"
    d.mkdir()
    rings = toy.cylinder([0.0, 0.5])
    good = {"csv_dir": "d"}
    latent = RING
    for n, r in enumerate(rings):
        np.savetxt(d / f"r{n}.csv", r, delimiter=",", header="x,y,z", comments="")
    if kind == "nan":
        (d / "r0.csv").write_text("x,y,z\n1,2,3\nnan,1,1\n" + "1,2,3\n" * 5)
    elif kind == "few":
        for f in d.iterdir():
            f.unlink()
        (d / "r0.csv").write_text("x,y,z\n1,2,3\n2,3,4\n")
    elif kind == "dims":
        (d / "r1.csv").write_text("x,y\n1,2\n2,3\n3,3\n")
    elif kind == "kernel":
        latent = [{"kernel": "cosine", "beta": 3, "time": True}]
    elif kind == "time_dim":
        latent = [{"kernel": "periodic", "beta": 12}]
    elif kind == "two_sources":
        good = {"csv_dir": "d", "npz": "x.npz"}
    elif kind == "typo":
        good = {"csv_dir": "d", "time_colum": "t"}
    elif kind == "missing":
        good = {"csv_dir": "nowhere"}
    cfg = {"data": good, "model": {"latent": latent}, "training": {"n_steps": 2}}
    if kind == "time_dim":
        cfg["model"]["time_dim"] = 1
    path = tmp_path / "cfg.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


@pytest.mark.parametrize(
    "kind, message",
    [
        ("nan", "NaN or inf"),
        ("few", "fewer points than needed"),
        ("dims", "inconsistent dimensions"),
        ("kernel", "kernel: Input should be 'gaussian'"),
        ("time_dim", "time dimension index 1 is out of range"),
        ("two_sources", "exactly one of csv_dir, npz, mcap"),
        ("typo", "time_colum"),
        ("missing", "does not exist"),
    ],
)
def test_bad_input_exit_code_2(tmp_path, capsys, kind, message):
    assert run(bad_case(tmp_path, kind), "--out", tmp_path / "m.npz") == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "m.npz").exists()


def test_missing_config_and_out_dir(tmp_path, capsys):
    assert run(tmp_path / "nope.yaml", "--out", tmp_path / "m.npz") == 2
    cfg = write_config(tmp_path, {"csv_dir": "x"})
    assert run(cfg, "--out", tmp_path / "no" / "m.npz") == 2
    assert "does not exist" in capsys.readouterr().err


def test_example_configs_are_valid():
    from pathlib import Path

    from handflow.plugins.manifold.cli import load_config

    folder = Path(__file__).resolve().parents[2] / "configs" / "train"
    for name in ("toy_cylinder", "motion_class_mcap", "construction_npz"):
        load_config(folder / f"{name}.yaml")
