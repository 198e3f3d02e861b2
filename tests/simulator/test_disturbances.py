"""Scene disturbances where the phase matters (plugins/simulator/scenes.py): added ball friction,
a ball taken out and put back, a pair of another size, a cap thread that binds, a cap of another
size."""

import math

import numpy as np
import pybullet as p
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from handflow.plugins.demo.ball_swap import BallSwapMotion
from handflow.plugins.hands.joints import GIFU
from handflow.plugins.simulator.scenes import BallsScene, CapScene
from handflow.plugins.simulator.simulation import Simulation


def _swap(sim, steps):
    motion = BallSwapMotion()
    for _ in range(steps):
        sim.set_targets(GIFU.names, motion.targets((sim.time % 2.0) / 2.0)[0])
        sim.step(1)


def _rolling(sim, k):
    return p.getDynamicsInfo(sim.scene.balls[k], -1, physicsClientId=sim.client)[6]


def test_a_friction_spell_sets_the_balls_rolling_friction_for_its_duration():
    with Simulation("gifu", "balls", {"frictions": [[0.5, 0.5, 0.05]]}, seed=0) as sim:
        _swap(sim, 121)
        assert _rolling(sim, 0) == pytest.approx(0.05) and _rolling(sim, 1) == pytest.approx(0.05)
        _swap(sim, 121)
        assert _rolling(sim, 0) == pytest.approx(BallsScene().rolling_friction)
        assert sim.scene_state()["frictions_done"] == 1


def test_a_removed_ball_is_out_of_the_hand_then_put_back_opposite_the_other():
    with Simulation("gifu", "balls", {"removals": [[1.0, 0.5]]}, seed=0) as sim:
        _swap(sim, 242)
        k = sim.scene.removed
        assert k is not None
        pos = sim.scene.palm_plane_positions(sim.client)
        assert np.isnan(pos[k]).all() and np.isfinite(pos[1 - k]).all()
        _swap(sim, 120)  # the lone ball goes on moving, then the other comes back
        assert sim.scene.removed is None and sim.scene_state()["removals_done"] == 1
        back = sim.scene.palm_plane_positions(sim.client)
        centre = np.array(sim.scene.cup_centre)
        # put back in contact, on the other side of the cup centre
        assert np.linalg.norm(back[0] - back[1]) == pytest.approx(2 * sim.scene.ball_radius, abs=4e-3)
        assert np.dot(back[0] - centre, back[1] - centre) < 0


def test_a_resize_swaps_the_pair_for_smaller_balls_in_the_same_direction():
    with Simulation("gifu", "balls", {"resizes": [[0.5, 0.014]]}, seed=0) as sim:
        _swap(sim, 120)
        before = sim.scene.palm_plane_positions(sim.client)
        old_ids = list(sim.scene.balls)
        _swap(sim, 2)
        after = sim.scene.palm_plane_positions(sim.client)
        radii = [p.getCollisionShapeData(b, -1, physicsClientId=sim.client)[0][3][0] for b in sim.scene.balls]
        assert sim.scene.balls != old_ids and radii == pytest.approx([0.014, 0.014])
        assert sim.scene_state()["resizes_done"] == 1
        d0, d1 = before[0] - before[1], after[0] - after[1]
        assert np.dot(d0, d1) / (np.linalg.norm(d0) * np.linalg.norm(d1)) > 0.99  # same pair direction
        assert set(sim.scene.bodies.values()) >= {"ball1", "ball2"}


def _cap_angle_under_torque(options, steps=240, torque=0.1):
    with Simulation("shadow", "cap", {"radius": 0.025, **options}, seed=0) as sim:
        angles = []
        for _ in range(steps):
            p.applyExternalTorque(sim.scene.bottle, 0, [0, 0, torque], p.WORLD_FRAME, physicsClientId=sim.client)
            sim.step(1)
            angles.append(sim.scene_state()["cap_angle"])
    return np.array(angles)


def test_a_blocked_cap_does_not_turn_while_blocked_and_turns_again_after():
    free = _cap_angle_under_torque({})
    blocked = _cap_angle_under_torque({"torques": [[0.25, 0.5, 10.0]]})
    assert free[-1] > 0.5  # 0.1 N·m beats the thread's 0.06 N·m
    i0, i1 = 61, 178  # inside the block 0.25–0.75 s
    assert abs(blocked[i1] - blocked[i0]) < 0.02 * abs(free[i1] - free[i0])
    assert blocked[-1] - blocked[190] > 0.01  # released


@pytest.mark.parametrize(
    "options, message",
    [
        ({"frictions": [[1.0, 2.0]]}, r"\[time_s, duration_s, rolling_friction\]"),
        ({"frictions": [[1.0, 2.0, 5.0]]}, "rolling_friction <= 1"),
        ({"removals": [[1.0, 0.0]]}, "0 < duration_s <= 10"),
        ({"resizes": [[1.0, 0.03]]}, "does not fit the cup"),
        ({"removals": "soon"}, r"\[time_s, duration_s\]"),
    ],
)
def test_bad_ball_disturbances_are_rejected_naming_the_form(options, message):
    with pytest.raises(ValueError, match=message):
        BallsScene(**options)


def test_a_swapped_cap_has_the_new_radius_and_keeps_its_angle_and_thread():
    torque = 0.1
    with Simulation("shadow", "cap", {"radius": 0.025, "swaps": [[0.5, 0.0175]]}, seed=0) as sim:
        for _ in range(118):
            p.applyExternalTorque(sim.scene.bottle, 0, [0, 0, torque], p.WORLD_FRAME, physicsClientId=sim.client)
            sim.step(1)
        before = sim.scene_state()
        sim.step(4)  # the swap at 0.5 s
        after = sim.scene_state()
        shape = p.getCollisionShapeData(sim.scene.bottle, -1, physicsClientId=sim.client)[0]
        assert shape[3][1] == pytest.approx(0.0175)  # the neck's radius (pybullet may reuse the body id)
        assert after["cap_radius"] == 0.0175 and after["swaps_done"] == 1 and before["cap_radius"] == 0.025
        assert before["cap_angle"] > 0.05 and after["cap_angle"] == pytest.approx(before["cap_angle"], abs=0.02)
        assert set(sim.scene.bodies.values()) == {"bottle", "cap"}
        for _ in range(120):  # no push: the thread's friction stops it again
            sim.step(1)
        assert abs(sim.scene_state()["cap_velocity"]) < 1e-3


def test_bad_cap_torques_are_rejected_naming_the_form():
    with pytest.raises(ValueError, match=r"\[time_s, duration_s, friction_torque\]"):
        CapScene(torques=[[1.0, 0.5]])
    with pytest.raises(ValueError, match=r"\[time_s, duration_s, friction_torque\]"):
        CapScene(torques=[[1.0, 0.5, 10**400]])  # an integer no float holds
    with pytest.raises(ValueError, match="time_s >= 0"):
        CapScene(torques=[[-1.0, 0.5, 1.0]])
    with pytest.raises(ValueError, match="0.01 <= radius_m <= 0.05"):
        CapScene(swaps=[[1.0, 0.2]])


_ENTRY_VALUES = st.one_of(
    st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=3)
)
_NUMBERS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-1.0, 12.0))
_SCHEDULES = st.one_of(
    _ENTRY_VALUES,
    st.lists(st.one_of(_ENTRY_VALUES, st.lists(_ENTRY_VALUES, max_size=4)), max_size=3),
    st.lists(st.lists(_NUMBERS, min_size=2, max_size=3), max_size=3),  # well-formed entries, odd numbers
)


@settings(max_examples=150, deadline=None)
@example(option=("balls", "pushes"), value=[[1.0, math.inf]])  # an infinite kick
@example(option=("cap", "swaps"), value=[[math.inf, 0.02]])  # a swap never due
@given(
    option=st.sampled_from(
        [("cap", "swaps"), ("cap", "torques")]
        + [("balls", o) for o in ("pushes", "turns", "holds", "frictions", "removals", "resizes")]
    ),
    value=_SCHEDULES,
)
def test_any_disturbance_schedule_from_a_config_is_accepted_or_refused_with_a_value_error(option, value):
    scene, name = option
    try:
        built = (CapScene if scene == "cap" else BallsScene)(**{name: value})
    except ValueError as exc:
        assert name in str(exc)
    else:  # accepted: every entry is finite and sorted by time
        entries = getattr(built, name)
        assert all(np.isfinite(e).all() for e in entries) and list(entries) == sorted(entries)
