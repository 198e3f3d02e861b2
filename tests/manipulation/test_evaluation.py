"""Evaluation helpers of the manipulation controllers (plugins/manipulation/evaluation.py,
disturbances.py, plots.py): the recovery definition, seeded disturbance timing, the per-class
summary, the plots, and short real ball-swap runs with each disturbance class."""

import numpy as np
import pytest

from handflow.plugins.manipulation.disturbances import (
    BALL_CLASSES,
    filled,
    rate_over_time,
    recovery_times,
    summarise,
)
from handflow.plugins.manipulation.evaluation import (
    BallSettings,
    EvalPlan,
    ball_swap,
    disturbance_classes,
    hardest_class,
)


def test_recovery_time_is_the_time_below_half_the_calm_rate_after_the_end():
    t = np.arange(0.0, 60.0, 0.05)
    calm = 30.0  # swaps/min = 0.5 swaps/s
    progress = np.where(t < 10, 0.5 * t, 5.0)  # stalls for good at 10 s
    progress = np.where(t > 40, 5.0 + 0.5 * (t - 40), progress)  # resumes at 40 s
    # 5 s: the 4 s trailing rate stays at the calm rate until 9 s: 0; 12 s: stalled for good;
    # 35 s: stalled, back to 15 swaps/min when the trailing 4 s hold 1 swap (42 s): 7 s
    starts = [5.0, 12.0, 35.0]
    rec = recovery_times(t, progress, starts, starts, calm)
    assert rec[0] == 0.0 and np.isinf(rec[1]) and rec[2] == pytest.approx(7.0, abs=0.06)
    np.testing.assert_allclose(
        recovery_times(t, -progress, [5.0, 35.0], [5.0, 35.0], calm, direction=-1.0), rec[[0, 2]]
    )
    assert recovery_times(t, progress, [35.0], [39.0], calm)[0] == pytest.approx(3.0, abs=0.06)  # from the end
    assert np.isinf(recovery_times(t, progress, [5.0], [5.0], 0.0)).all()  # a controller that never swaps
    summary = summarise(rec, cycle_s=2.0)
    assert summary == {
        "recovered_share": pytest.approx(1 / 3),
        "failures": 1,
        "recovery_s": pytest.approx(3.5, abs=0.03),
    }


def test_progress_gaps_hold_the_last_value_and_the_rate_follows_the_slope():
    np.testing.assert_array_equal(filled([np.nan, 1.0, np.nan, 3.0]), [0.0, 1.0, 1.0, 3.0])
    t = np.arange(0.0, 10.0, 0.05)
    rate = rate_over_time(t, 0.5 * t, window_s=2.0)
    np.testing.assert_allclose(rate[t >= 2.0], 30.0)


def test_seed_zero_disturbs_at_the_same_phase_other_seeds_within_one_cycle():
    plan = EvalPlan()
    times = np.array(plan.disturbances())
    assert times[0] == pytest.approx(10.5) and len(times) == 3
    assert len(EvalPlan.quick().disturbances()) == 1
    assert np.allclose(np.mod(times - times[0], 2.0), 0.0)  # 2 s hand cycle
    shifted = np.array(plan.disturbances(seed=3))
    assert np.all((shifted >= times) & (shifted < times + 2.0)) and not np.allclose(shifted, times)
    assert plan.disturbances(seed=3) == plan.disturbances(seed=3)


def test_disturbance_classes_keep_rate_and_recovered_share_per_controller():
    detail = {"rate": 20.0, "recovered_share": 0.5, "failures": 1, "calm_rate": 28.0}
    classes = {
        "hold": {"open_loop": detail, "closed_loop": {**detail, "rate": 26.0}},
        "push": {"open_loop": {**detail, "rate": 25.0}},
    }
    short = disturbance_classes(classes)
    assert short["hold"]["closed_loop"] == {"rate": 26.0, "recovered_share": 0.5}
    assert hardest_class(classes) == "hold"


def test_rate_plots_are_written_with_a_panel_per_class(tmp_path):
    from handflow.plugins.manipulation.plots import plot_rates

    t = np.arange(0.0, 20.0, 0.05)
    run = {"times": t, "progress": 0.5 * t}
    runs = {0: {"open_loop": {"calm": run, "hold": ((5.0, 15.0), run)}}}
    path = plot_rates(runs, {"hold": BALL_CLASSES["hold"]}, "progress", tmp_path / "plots", "balls", 2.0)
    assert path.is_file() and path.stat().st_size > 10_000


@pytest.mark.slow
@pytest.mark.parametrize("cls", sorted(BALL_CLASSES))
def test_every_ball_disturbance_class_perturbs_the_open_loop_swapping(ball_manifold_file, cls):
    from handflow.plugins.manipulation import ManipulationManifold

    man = ManipulationManifold.load(ball_manifold_file)
    base = BallSettings(duration_s=14.0, camera=False)
    calm = ball_swap(man, "open_loop", base)
    options = BALL_CLASSES[cls].scene_options([10.5])
    disturbed = ball_swap(man, "open_loop", BallSettings(**{**base.__dict__, "scene_options": options}))
    assert abs(calm["progress"][-1]) >= 5
    before, after = calm["times"] < 10.5, calm["times"] > 10.6
    np.testing.assert_allclose(disturbed["progress"][before], calm["progress"][before])
    # the balls leave the calm run's track (a push by 0.07 swaps, then the rake catches up) ...
    assert np.max(np.abs(filled(disturbed["progress"])[after] - calm["progress"][after])) >= 0.05
    if cls != "push":  # ... every other class costs the open loop swaps
        assert abs(filled(disturbed["progress"])[-1]) <= abs(calm["progress"][-1]) - 0.4


def test_an_unknown_ball_controller_is_rejected(ball_manifold):
    with pytest.raises(ValueError, match="closed_loop"):
        ball_swap(ball_manifold, "magic", BallSettings(duration_s=1.0, camera=False))


@pytest.mark.slow
@pytest.mark.parametrize("radius_cm", [1.5, 3.5])
def test_quick_evaluation_turns_the_smallest_and_largest_cap_forward(radius_cm):
    from handflow.framework.files.resources import shipped
    from handflow.plugins.manipulation import ManipulationManifold
    from handflow.plugins.manipulation.evaluation import cap_turning

    man = ManipulationManifold.load(shipped("models") / "cap_constructed.npz")
    res = cap_turning(man, radius_cm, EvalPlan.quick().cap)
    assert res["grasp_complete"]
    assert res["deg_per_cycle"] >= 10.0
    assert len(res["per_cycle_deg"]) == EvalPlan.quick().cap.cycles


@pytest.mark.slow
def test_the_cap_closed_loop_regrasps_a_smaller_cap_that_stops_the_open_loop():
    from handflow.framework.files.resources import shipped
    from handflow.plugins.manipulation import ManipulationManifold
    from handflow.plugins.manipulation.disturbances import CAP_CLASSES
    from handflow.plugins.manipulation.evaluation import CapSettings, cap_turning

    man = ManipulationManifold.load(shipped("models") / "cap_constructed.npz")
    settings = CapSettings(cycles=8)
    swap = CAP_CLASSES["cap_swap_small"].scene_options([7.0])  # the turning starts at ≈ 4.2 s
    runs = {name: cap_turning(man, 2.5, settings, 0, swap, name) for name in ("open_loop", "closed_loop")}
    assert runs["open_loop"]["regrasps"] == 0 and runs["closed_loop"]["regrasps"] == 1
    last = {name: sum(run["per_cycle_deg"][-2:]) / 2 for name, run in runs.items()}
    assert last["open_loop"] < 20.0 and last["closed_loop"] > 30.0  # turning again only with the regrasp
    with pytest.raises(ValueError, match="closed_loop"):
        cap_turning(man, 2.5, settings, controller="magic")


@pytest.mark.parametrize("flag", ["--seeds", "--jobs"])
def test_evaluate_command_rejects_fewer_than_one_seed_or_job(flag, capsys):
    import argparse

    from handflow.plugins.manipulation.cli import register_evaluate

    parser = argparse.ArgumentParser()
    register_evaluate(parser)
    args = parser.parse_args(["--quick", flag, "0"])
    assert args.func(args) == 2
    assert f"{flag} must be >= 1" in capsys.readouterr().err
