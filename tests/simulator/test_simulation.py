"""Physics behaviour of the plain Simulation: limits, couplings, collision correction, cap turning."""

import numpy as np
import pytest

from handflow.plugins.demo.cap_turning import CapTurningDemonstrator
from handflow.plugins.hands.joints import GIFU, SHADOW
from handflow.plugins.simulator.simulation import Simulation

FLEX = [f"{f}J{k}" for f in ("FF", "MF", "RF", "LF") for k in (3, 2, 1)]


def test_joint_limits_hold_under_targets_beyond_them():
    with Simulation("shadow") as sim:
        sim.set_targets(SHADOW.names, SHADOW.upper + 1.0)
        sim.step(200)
        q = sim.joint_positions()
        assert np.all(q <= SHADOW.upper + 0.02)
        assert np.all(sim.targets == SHADOW.upper)
        sim.set_targets(SHADOW.names, SHADOW.lower - 1.0)
        sim.step(200)
        assert np.all(sim.joint_positions() >= SHADOW.lower - 0.02)


def test_shadow_distal_is_raised_to_the_middle_joint():
    with Simulation("shadow") as sim:
        sim.set_targets(["FFJ2", "FFJ1"], [1.0, 0.2])
        sim.step(200)
        js = sim.joint_state()
        q = dict(zip(js.names, js.positions))
        assert q["FFJ1"] == pytest.approx(1.0, abs=0.05)
        assert q["FFJ2"] == pytest.approx(1.0, abs=0.05)


def test_gifu_dip_follows_pip_whatever_is_commanded():
    with Simulation("gifu") as sim:
        sim.set_targets(["MF_J3", "MF_J4"], [0.9, 0.0])
        sim.step(200)
        q = dict(zip(GIFU.names, sim.joint_positions()))
        assert q["MF_J4"] == pytest.approx(0.9, abs=0.05)
        assert q["MF_J3"] == pytest.approx(0.9, abs=0.05)


def test_unknown_joint_names_are_rejected_with_the_valid_names():
    with Simulation("gifu") as sim:
        with pytest.raises(ValueError, match="no joint.*FFJ3.*TH_J1"):
            sim.set_targets(["FFJ3"], [0.1])
        with pytest.raises(ValueError, match="finite"):
            sim.set_targets(["FF_J2"], [np.nan])


def test_joints_not_named_keep_their_last_target():
    with Simulation("shadow") as sim:
        sim.set_targets(["MFJ3"], [0.8])
        sim.set_targets(["FFJ3"], [0.5])
        sim.step(150)
        q = dict(zip(SHADOW.names, sim.joint_positions()))
        assert q["MFJ3"] == pytest.approx(0.8, abs=0.05) and q["FFJ3"] == pytest.approx(0.5, abs=0.05)


def test_fingers_closing_on_a_small_cap_are_stopped_by_it():
    with Simulation("shadow", "cap", {"radius": 0.015}) as sim:
        sim.set_targets(FLEX, [1.5] * len(FLEX))
        sim.step(240)
        q = dict(zip(SHADOW.names, sim.joint_positions()))
        contacts = sim.contacts()
    with Simulation("shadow", "empty") as free:
        free.set_targets(FLEX, [1.5] * len(FLEX))
        free.step(240)
        q_free = dict(zip(SHADOW.names, free.joint_positions()))
    assert q_free["MFJ3"] == pytest.approx(1.5, abs=0.05)
    assert q["MFJ3"] < 1.5 - 0.3  # collision-corrected posture differs from the target
    touching = {s for s, b in zip(contacts.segments, contacts.bodies) if b == "cap"}
    assert "MF_distal" in touching
    assert contacts.forces.min() >= 0 and contacts.forces.max() > 1.0


def _sweep(sim, closed: bool, steps: int = 240) -> float:
    demo = CapTurningDemonstrator()
    var = demo.variation(np.random.default_rng(0))
    keys = demo.key_postures(0.025, var)
    back, front = (keys[1], keys[2]) if closed else (keys[0], keys[3])
    sim.set_targets(SHADOW.names, back)
    sim.step(240)
    start = sim.scene_state()["cap_angle"]
    for i in range(steps):
        w = 0.5 - 0.5 * np.cos(np.pi * (i + 1) / steps)
        sim.set_targets(SHADOW.names, back * (1 - w) + front * w)
        sim.step(1)
    return sim.scene_state()["cap_angle"] - start


def test_turning_with_contact_rotates_the_cap_and_an_open_hand_does_not():
    with Simulation("shadow", "cap", {"radius": 0.025}) as sim:
        assert abs(_sweep(sim, closed=False)) < 0.01
    with Simulation("shadow", "cap", {"radius": 0.025}) as sim:
        assert abs(_sweep(sim, closed=True)) > 0.3


def test_render_draws_the_scene_at_the_requested_size():
    with Simulation("gifu", "balls") as sim:
        img = sim.render(64, 48)
    assert img.shape == (48, 64, 3) and img.dtype == np.uint8
    assert img.std() > 10  # not a blank frame


@pytest.mark.parametrize(
    "scene, opts, key",
    [("grasp", {"object": "cylinder", "position": [0.01, 0.0]}, "object_z"), ("balls", {}, "ball2_z")],
)
def test_scene_state_reports_object_poses(scene, opts, key):
    with Simulation("gifu" if scene == "balls" else "shadow", scene, opts) as sim:
        sim.step(60)
        state = sim.scene_state()
    assert key in state and np.isfinite(state[key])


def test_bad_scene_options_name_the_valid_ones():
    with pytest.raises(ValueError, match="valid:.*radius"):
        Simulation("shadow", "cap", {"radius_cm": 2})
    with pytest.raises(ValueError, match="box, cylinder, sphere"):
        Simulation("shadow", "grasp", {"object": "cone"})
