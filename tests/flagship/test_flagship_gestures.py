"""Gesture classes, the script, and the path that regenerates the flagship's shipped models."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from handflow.plugins.demo import gestures as G
from handflow.plugins.glove.frames_io import load_frames
from handflow.plugins.hands.joints import DEG, HUMAN
from handflow.plugins.segmenter.cli import register_train_classes
from handflow.plugins.segmenter.datasets import load_dataset
from handflow.plugins.segmenter.models import load_candidates

REPO = Path(__file__).resolve().parents[2]
MODELS = REPO / "configs" / "models" / "gestures"


def test_script_reports_the_ground_truth_and_loops():
    script = G.GestureScript([("grasp", 2.0), ("pinch", 3.0)])
    assert script.duration_s == 5.0
    assert script.labels([0.0, 1.99, 2.0, 4.9, 5.0, 7.5]) == ["grasp", "grasp", "pinch", "pinch", "grasp", "pinch"]


def test_postures_stay_in_limits_and_obey_the_spread_constraint():
    q = G.GestureScript(seed=3).joints(np.arange(0, 32, 0.02))
    assert np.all(q >= HUMAN.lower - 1e-12) and np.all(q <= HUMAN.upper + 1e-12)
    ff, lf, mf, rf = (q[:, HUMAN.index(f"{f}_spread")] for f in ("ff", "lf", "mf", "rf"))
    np.testing.assert_allclose(ff, lf)
    np.testing.assert_allclose(mf, rf)
    np.testing.assert_allclose(mf, ff / 3)


def test_gesture_is_periodic_and_its_variation_is_seeded():
    plain = G.Gesture("wave", variation=False)
    t = np.linspace(0, 3, 50)
    np.testing.assert_allclose(plain.joints(t), plain.joints(t + plain.period_s), atol=1e-12)
    a, b, c = (G.Gesture("wave", seed=s).joints(t) for s in (1, 1, 2))
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 1 * DEG


def test_classes_differ_and_script_changes_are_smooth():
    t = np.arange(0, 4, 0.02)
    means = {name: G.Gesture(name, variation=False).joints(t) for name in G.GESTURES}
    for x in means:
        for y in means:
            if x < y:
                assert np.abs(means[x] - means[y]).max() > 20 * DEG, (x, y)
    q = G.GestureScript().joints(np.arange(0, 32, 0.02))
    assert np.abs(np.diff(q, axis=0)).max() < 8 * DEG  # no jump at the gesture changes (50 Hz)


def test_bad_script_is_refused_with_the_known_gestures():
    with pytest.raises(ValueError, match="dance.*grasp"):
        G.GestureScript([("dance", 4.0)])
    with pytest.raises(ValueError, match="blend_s"):
        G.GestureScript([("grasp", 0.2)])


def test_shipped_frames_are_the_default_script(tmp_path):
    out = tmp_path / "frames.npy"
    assert G.main(["frames", "--out", str(out)]) == 0
    shipped = REPO / "configs" / "models" / "gestures" / "demo_frames.npy"
    np.testing.assert_array_equal(load_frames(out), load_frames(shipped))
    assert load_frames(out).shape == (1600, 22)


def test_flagship_graphs_use_the_models_joints():
    for graph in ("demo.yaml", "demo_segment_only.yaml"):
        nodes = yaml.safe_load((REPO / "configs" / graph).read_text())["nodes"]
        seg = next(n for n in nodes if n["id"] == "segmenter")["params"]
        assert tuple(seg["joints"]) == G.SEGMENT_JOINTS
        assert (REPO / "configs" / seg["models"]).resolve() == MODELS
    candidates = load_candidates(MODELS)
    assert candidates.classes == sorted(G.GESTURES)
    assert all(c.model.Y_.shape[1] == len(G.SEGMENT_JOINTS) for c in candidates.models.values())


def test_shipped_models_recognise_the_script_offline():
    """Each gesture of the demo script is reconstructed best by its own manifold (every 8th sample)."""
    from handflow.plugins.hands.joints import SHADOW
    from handflow.plugins.mapping.calibration import (
        DEFAULT_CALIBRATION,
        DEFAULT_PROFILE,
        load_calibration,
        load_profile,
    )
    from handflow.plugins.mapping.human import HumanHandMapping
    from handflow.plugins.mapping.robot import ShadowHandMapping

    frames = load_frames(MODELS / "demo_frames.npy")[::8]
    human = HumanHandMapping(load_profile(DEFAULT_PROFILE), load_calibration(DEFAULT_CALIBRATION))
    Y = ShadowHandMapping().map(human.map(frames))[:, [SHADOW.index(j) for j in G.SEGMENT_JOINTS]]
    truth = np.array(G.GestureScript().labels(np.arange(0, 32, 8 / 50)))
    candidates = load_candidates(MODELS)
    errors = np.column_stack([candidates.models[c].project(Y)[1] for c in candidates.classes])
    best = np.array(candidates.classes)[errors.argmin(axis=1)]
    for g in G.GESTURES:
        assert np.mean(best[truth == g] == g) > 0.9, g


def test_regeneration_path_on_a_reduced_scale(tmp_path):
    """record → dataset → handflow train-classes → models the segmenter loads (the documented commands)."""
    rec, ds, models = tmp_path / "gestures.mcap", tmp_path / "gestures.npz", tmp_path / "models"
    assert (
        G.main(
            [
                "record",
                "--out",
                str(rec),
                "--sequences",
                "3",
                "--duration",
                "1.2",
                "--rate",
                "25",
                "--gestures",
                "grasp,pinch",
            ]
        )
        == 0
    )
    assert G.main(["dataset", str(rec), "--out", str(ds)]) == 0
    dataset = load_dataset(ds)
    assert dataset.classes == ["grasp", "pinch"]
    assert dataset.columns == list(G.SEGMENT_JOINTS)
    assert [len(dataset.split(s)) for s in ("train", "validation", "test")] == [2, 2, 2]
    assert all(t.data.shape == (30, len(G.SEGMENT_JOINTS)) for t in dataset.train)

    import argparse

    parser = argparse.ArgumentParser()
    register_train_classes(parser)
    args = parser.parse_args([str(ds), "--out", str(models), "--steps", "5"])
    assert args.func(args) == 0
    assert json.loads((models / "classes.json").read_text())["classes"] == {"grasp": "grasp.npz", "pinch": "pinch.npz"}
    assert load_candidates(models).classes == ["grasp", "pinch"]


def test_dataset_from_a_recording_without_segments_says_how_to_record(tmp_path, capsys):
    from handflow.framework.files.mcap_writer import McapWriter
    from handflow.framework.messages import Array

    path = tmp_path / "other.mcap"
    with McapWriter(path, flush_interval_s=None) as w:
        w.write("handflow/x/a/out", Array(data=[1.0]), 1)
    assert G.main(["dataset", str(path), "--out", str(tmp_path / "d.npz")]) == 2
    assert "handflow.plugins.demo.gestures record" in capsys.readouterr().err


def test_record_refuses_too_few_sequences(tmp_path, capsys):
    assert G.main(["record", "--out", str(tmp_path / "r.mcap"), "--sequences", "2"]) == 2
    assert "--sequences must be" in capsys.readouterr().err
