"""Evaluation helpers of the manipulation controllers (plugins/manipulation/evaluation.py): the recovery
definition and a short real ball-swap run with a turn-back disturbance."""

import numpy as np
import pytest

from handflow.plugins.manipulation.evaluation import (
    DISTURBANCE_CLASSES,
    BallSettings,
    EvalPlan,
    ball_swap,
    disturbance_classes,
    recoveries,
)


def test_recovery_needs_half_the_calm_rate_within_ten_seconds():
    t = np.arange(0.0, 60.0, 0.05)
    calm = 30.0  # swaps/min = 0.5 swaps/s
    progress = np.where(t < 10, 0.5 * t, 5.0)  # stalls for good at 10 s
    progress = np.where(t > 40, 5.0 + 0.5 * (t - 40), progress)  # resumes at 40 s
    # disturbance at 5 s: the window 5–9 s still runs at the calm rate; 12 s: stalled for 10 s;
    # 35 s: swaps resume at 40 s, 1 swap in the window 40–44 s = exactly 50 %
    assert recoveries(t, progress, [5.0, 12.0, 35.0], calm) == 2
    assert recoveries(t, -progress, [5.0, 35.0], calm, direction=-1.0) == 2
    assert recoveries(t, progress, [5.0], 0.0) == 0  # a controller that never swaps


def test_quick_plan_disturbs_at_the_same_open_loop_phase():
    plan = EvalPlan.quick()
    times = plan.disturbances()
    assert times[0] == pytest.approx(10.5) and len(times) == 2
    assert np.allclose(np.mod(np.array(times) - times[0], 2.0), 0.0)  # 2 s hand cycle


def test_disturbance_classes_gather_rate_and_recovered_share_per_controller():
    row = {"swaps_per_min": 30.0, "disturbances": 4}
    for i, (_, key) in enumerate(DISTURBANCE_CLASSES.values()):
        row[f"swaps_per_min_disturbed{key}"], row[f"recoveries{key}"] = 20.0 + i, i
    classes = disturbance_classes({"open_loop": row, "closed_loop": {**row, "recoveries_held": 4}})
    assert set(classes) == {"turn_back", "push", "hold"}
    assert classes["push"]["open_loop"] == {"rate": 21.0, "recovered_share": 0.25}
    assert classes["hold"]["closed_loop"]["recovered_share"] == 1.0
    assert classes["hold"]["open_loop"]["recovered_share"] == 0.5


@pytest.mark.slow
def test_a_turn_back_costs_the_open_loop_swaps(ball_manifold_file):
    from handflow.plugins.manipulation import ManipulationManifold

    man = ManipulationManifold.load(ball_manifold_file)
    base = BallSettings(duration_s=14.0, camera=False)
    calm = ball_swap(man, False, base)
    turned = ball_swap(man, False, BallSettings(**{**base.__dict__, "turn_times_s": (10.5,), "turn_deg": 90.0}))
    assert abs(calm["progress"][-1]) >= 5
    assert abs(turned["progress"][-1]) <= abs(calm["progress"][-1]) - 0.4


@pytest.mark.slow
@pytest.mark.parametrize("radius_cm", [1.5, 3.5])
def test_quick_evaluation_turns_the_smallest_and_largest_cap_forward(radius_cm):
    from handflow.framework.resources import shipped
    from handflow.plugins.manipulation import ManipulationManifold
    from handflow.plugins.manipulation.evaluation import cap_turning

    man = ManipulationManifold.load(shipped("models") / "cap_constructed.npz")
    res = cap_turning(man, radius_cm, EvalPlan.quick().cap)
    assert res["grasp_complete"]
    assert res["deg_per_cycle"] >= 10.0
    assert len(res["per_cycle_deg"]) == EvalPlan.quick().cap.cycles
