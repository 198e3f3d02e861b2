"""Commands grasp-som / grasp-experience / evaluate grasping: files, plots and bad input (docs/grasping.md)."""

import argparse

import numpy as np
import pytest

from handflow.plugins.grasp import cli
from handflow.plugins.grasp.evaluation import evaluate_grasping, gamma_factors, sign_test
from handflow.plugins.grasp.experience import ExperienceBase, GraspDataset
from handflow.plugins.grasp.generation import PREGRASP_RANGES
from handflow.plugins.grasp.hand_layout import hand_layout
from handflow.plugins.grasp.som import load_som

NAMES = hand_layout("shadow").finger_joints


def call(register, argv):
    parser = argparse.ArgumentParser()
    register(parser)
    args = parser.parse_args(argv)
    return args.func(args)


@pytest.fixture
def grasps(tmp_path):
    rng = np.random.default_rng(0)
    n = 40
    path = tmp_path / "grasps.npz"
    GraspDataset(
        NAMES,
        rng.uniform(0, 1.2, (n, len(NAMES))),
        ["box"] * 20 + ["sphere"] * 20,
        np.zeros((n, 4)),
        [["FF_distal"]] * n,
        np.ones(n),
    ).save(path)
    return path


def test_grasp_som_trains_resumes_and_plots(tmp_path, grasps, capsys):
    som_path, umat, nodes = tmp_path / "som.npz", tmp_path / "u.png", tmp_path / "nodes.png"
    assert (
        call(
            cli.register_train_som,
            [
                str(grasps),
                "--object",
                "box",
                "--out",
                str(som_path),
                "--rows",
                "4",
                "--cols",
                "5",
                "--epochs",
                "20",
                "--umatrix",
                str(umat),
                "--nodes",
                str(nodes),
                "--extract",
                "2",
            ],
        )
        == 0
    )
    som, meta = load_som(som_path)
    assert som.nodes_.shape == (4, 5, len(NAMES)) and meta["object"] == "box" and meta["names"] == list(NAMES)
    assert umat.stat().st_size > 1000
    import matplotlib.pyplot as plt

    img = plt.imread(nodes)
    assert img.shape[0] > 200 and img[..., :3].std() > 0.05  # rendered hands, not a blank canvas
    assert ExperienceBase.load(som_path).kind == "som"
    resumed = tmp_path / "som2.npz"
    assert (
        call(
            cli.register_train_som,
            [str(grasps), "--object", "sphere", "--resume", str(som_path), "--out", str(resumed)],
        )
        == 0
    )
    som2, _ = load_som(resumed)
    assert som2.n_updates_ == 2 and len(som2.qe_history_) == len(som.qe_history_) + 10


def test_bad_input_exits_2_with_advice(tmp_path, grasps, capsys):
    assert call(cli.register_train_som, [str(grasps), "--object", "cylinder", "--out", str(tmp_path / "s.npz")]) == 2
    assert "no grasps of 'cylinder'" in capsys.readouterr().err
    assert call(cli.register_train_som, [str(grasps), "--lr", "fast", "--out", str(tmp_path / "s.npz")]) == 2
    assert "start,end" in capsys.readouterr().err
    assert call(cli.register_generate, ["--objects", "teapot", "--out", str(tmp_path)]) == 2
    assert "box,cylinder,sphere" in capsys.readouterr().err
    assert call(cli.register_generate, ["--objects", "box,cylinder", "--trials", "box=5", "--out", str(tmp_path)]) == 2
    assert "missing ['cylinder']" in capsys.readouterr().err
    assert call(cli.register_generate, ["--trials", "box=many", "--out", str(tmp_path)]) == 2
    assert "object=count" in capsys.readouterr().err
    assert call(cli.register_evaluate, ["--quick", "--experience", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err
    assert "som_box.npz" in err and "grasp-experience" in err


def test_generate_writes_a_dataset_and_soms(tmp_path, capsys):
    out = tmp_path / "exp"
    assert (
        call(cli.register_generate, ["--objects", "sphere", "--trials", "sphere=6", "--out", str(out), "--seed", "3"])
        == 0
    )
    data = GraspDataset.load(out / "grasps.npz")
    assert data.metadata["counts"]["sphere"]["trials"] == 6 and data.names == tuple(NAMES)
    assert data.metadata["pregrasp_ranges"]["THJ5"] == list(PREGRASP_RANGES["THJ5"])  # random pre-grasps by default
    assert set(data.objects) <= {"sphere"}


def test_evaluation_pools_repeats_with_jittered_gamma(capsys):
    assert gamma_factors(3) == pytest.approx([1.0, 0.98, 1.02])
    one_pose = {"x": (0.035,), "y": (0.0,), "gap": (0.005,), "yaw_deg": (-30.0,)}  # the centred cylinder
    result = evaluate_grasping(cli.DEFAULT_EXPERIENCE, one_pose, ("cylinder",), repeats=2)
    assert result["grasps_evaluated"] == 6 and result["cylinder"]["n_valid"] == 2  # 2 runs × 3 conditions
    assert result["gamma_factors"] == pytest.approx([1.0, 0.98])
    assert all(result["overall"][c] in (0.0, 0.5, 1.0) for c in ("experience", "no_experience", "shared_som"))
    for cond in ("experience", "shared_som"):  # paired: share difference = (wins − losses) / poses
        pair = result["cylinder"]["paired"][cond]
        assert pair == result["overall"]["paired"][cond] and 0.0 <= pair["p_sign"] <= 1.0
        diff = result["cylinder"][cond] - result["cylinder"]["no_experience"]
        assert diff == pytest.approx((pair["wins"] - pair["losses"]) / 2)
    assert call(cli.register_evaluate, ["--quick", "--repeats", "0"]) == 2
    assert "repeats must be ≥ 1" in capsys.readouterr().err


def test_sign_test_counts_only_poses_that_differ():
    assert sign_test(0, 0) == {"wins": 0, "losses": 0, "p_sign": 1.0}
    assert sign_test(9, 1)["p_sign"] == pytest.approx(22 / 1024)  # 2 · P(X ≤ 1), X ~ B(10, ½)
    assert sign_test(5, 5)["p_sign"] == pytest.approx(1.0)
