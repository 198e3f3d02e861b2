"""The grasp controller's phases on scripted contact sequences (docs/grasping.md, thesis 4.1)."""

import numpy as np
import pytest

from handflow.plugins.grasp.controller import HOLD, WRAP, ControllerConfig, ExperienceGraspController
from handflow.plugins.grasp.experience import ExperienceBase
from handflow.plugins.grasp.hand_layout import hand_layout
from handflow.plugins.hands.joints import HAND_MODELS

MODEL = HAND_MODELS["shadow"]
LAYOUT = hand_layout("shadow")
CFG = ControllerConfig(gamma=1.2, lam=1.5, rate_hz=60.0, pregrasp={"THJ5": -0.4, "THJ4": 0.2})


def make(experience=None, config=CFG):
    return ExperienceGraspController(LAYOUT, MODEL.lower, MODEL.upper, experience, config)


def col(name):
    return LAYOUT.names.index(name)


def run(ctl, contacts_per_cycle, q=None):
    """Kinematic plant: the hand reaches every target exactly; returns the targets per cycle."""
    q = ctl.pregrasp.copy() if q is None else q
    out = []
    for touched in contacts_per_cycle:
        q = ctl.step(q, touched)
        out.append(q.copy())
    return np.array(out)


def test_closing_heuristic_speeds_and_phase_sequence():
    ctl = make()
    t = run(ctl, [[]] * 5)
    assert ctl.phase == "B"
    dt = 1 / 60
    step = np.diff(t[1:], axis=0)[-1]
    assert step[col("FFJ3")] == pytest.approx(1.5 * 1.2 * dt)  # proximal: λ·γ
    assert step[col("FFJ2")] == pytest.approx(1.2 * dt)  # distal: γ
    assert step[col("THJ4")] == pytest.approx(1.5 * 1.2 * dt)  # thumb proximal closing joint
    for fixed in ("FFJ4", "THJ5", "THJ3", "LFJ5", "WRJ1"):  # spread/rotation joints do not close
        assert step[col(fixed)] == 0.0


def test_finger_holds_once_its_tip_touches():
    ctl = make()
    t = run(ctl, [[]] * 5 + [["FF_distal"]] * 10)
    assert ctl.phase == "C" and ctl.mode["FF"] == HOLD
    ff = [col(n) for n in ("FFJ3", "FFJ2", "FFJ1")]
    mf = [col(n) for n in ("MFJ3", "MFJ2", "MFJ1")]
    np.testing.assert_allclose(t[6:, ff], t[5:6, ff].repeat(9, 0))  # frozen at the contact posture
    assert np.all(np.diff(t[5:, mf], axis=0) > 0)  # the other fingers keep closing


def test_non_tip_contact_holds_proximal_and_closes_distal_joints():
    ctl = make()
    t = run(ctl, [[]] * 5 + [["FF_middle"]] * 6)
    assert ctl.mode["FF"] == WRAP
    d = np.diff(t[6:], axis=0)
    assert np.all(d[:, col("FFJ3")] == 0) and np.all(d[:, col("FFJ2")] == 0)
    assert np.all(d[:, col("FFJ1")] == pytest.approx(1.2 / 60))


def test_tip_contact_lost_resumes_closing_but_a_flicker_does_not():
    ctl = make()
    t = run(ctl, [[]] * 5 + [["MF_distal"]] * 3 + [[]] * 2 + [["MF_distal"]])
    assert ctl.mode["MF"] == HOLD  # 2 cycles without contact: debounced
    assert t[-1, col("MFJ3")] == t[5, col("MFJ3")]
    t = run(ctl, [[]] * (CFG.release_cycles + 3), q=t[-1])
    assert ctl.mode["MF"] != HOLD  # really lost: the finger closes again
    assert t[-1, col("MFJ3")] > t[-3, col("MFJ3")]


def experience_base():
    """Three grasps: A and B agree with the hand on the index finger, B also on the thumb."""
    names = LAYOUT.finger_joints
    base = np.zeros((3, len(names)))
    ix = {n: k for k, n in enumerate(names)}
    base[:, ix["MFJ3"]] = (0.9, 0.3, 0.6)  # what the sub-targets tell the middle finger
    base[:, ix["THJ2"]] = (0.5, 0.0, 0.5)
    base[2, ix["FFJ3"]] = 3.0  # posture 2 disagrees on the index finger
    return ExperienceBase(base, names, "database")


def test_rematches_exactly_when_contacts_change_and_pcp_ignores_untouched_fingers():
    ctl = make(experience_base(), ControllerConfig(gamma=1.2, lam=1.5, pregrasp=CFG.pregrasp, rematch_cycles=0))
    q = np.zeros(len(LAYOUT.names))  # hand open: matches care about FF/TH only
    ctl.step(q, ["FF_proximal"])  # a contact ends phase A at once
    assert ctl.phase == "C" and ctl.n_matches == 1
    assert ctl.match_index in (0, 1)  # PCP over FFJ4, FFJ3 only: posture 2 is out
    first = ctl.match_index
    ctl.step(q, ["FF_proximal"])
    assert ctl.n_matches == 1  # same contacts: no new search
    ctl.step(q, ["FF_proximal", "TH_proximal"])  # thumb joints THJ5..THJ2 now specified (all 0)
    assert ctl.n_matches == 2 and ctl.match_index == 1 and first == 0
    # the untouched middle finger heads for the new best match's sub-target (MFJ3 = 0.3)
    for _ in range(40):
        ctl.step(q, ["FF_proximal", "TH_proximal"])
    assert ctl.targets[col("MFJ3")] == pytest.approx(0.3) and ctl.n_matches == 2


def test_rematch_waits_until_a_changed_contact_set_has_persisted():
    ctl = make(experience_base(), ControllerConfig(pregrasp=CFG.pregrasp, rematch_cycles=3, release_cycles=0))
    q = np.zeros(len(LAYOUT.names))
    for _ in range(3):
        ctl.step(q, ["FF_proximal"])
    assert ctl.n_matches == 0  # a new contact set: not yet settled
    ctl.step(q, ["FF_proximal"])
    assert ctl.n_matches == 1
    for touched in (["FF_proximal", "TH_proximal"], ["FF_proximal"]) * 3:  # the thumb contact flickers
        ctl.step(q, touched)
    assert ctl.n_matches == 1
    for _ in range(4):  # … until it stays
        ctl.step(q, ["FF_proximal", "TH_proximal"])
    assert ctl.n_matches == 2


def test_phase_b_approaches_the_best_match_over_all_joints():
    names = LAYOUT.finger_joints
    posture = np.zeros(len(names))
    posture[names.index("MFJ3")] = 0.3
    posture[names.index("THJ5")] = -0.2
    ctl = make(
        ExperienceBase(posture[None], names),
        ControllerConfig(pregrasp=CFG.pregrasp, approach_speed=0.6, steer="all", steer_before_contact=True),
    )
    t = ctl.step(ctl.pregrasp.copy(), [])  # pre-grasp reached: A → B, best match chosen
    assert ctl.phase == "B" and ctl.n_matches == 1
    mf = [t[col("MFJ3")]]
    for _ in range(40):  # kinematic plant: q follows the targets
        t = ctl.step(t, [])
        mf.append(t[col("MFJ3")])
    np.testing.assert_allclose(mf[:29], np.arange(1, 30) * 0.01)  # rate-limited approach to 0.3, no jump
    assert t[col("THJ5")] == pytest.approx(-0.2)  # a joint the heuristic never moves: from the match
    assert mf[-1] > 0.3  # reached, then closed by the heuristic


def test_grip_presses_held_fingers_when_finished():
    ctl = make(config=ControllerConfig(pregrasp={}, squeeze=0.1))
    q = ctl.pregrasp.copy()
    touching = ["TH_distal", "FF_distal", "MF_distal", "RF_distal", "LF_distal"]
    q = ctl.step(q, [])
    out = ctl.step(q, touching)
    assert ctl.phase == "grip" and ctl.finished(q)
    for name in ("FFJ3", "FFJ2", "THJ4", "THJ1"):
        assert out[col(name)] == pytest.approx(q[col(name)] + 0.1)  # pressed into the object
    np.testing.assert_array_equal(ctl.step(q, []), out)  # and kept from then on


def test_refuses_experience_from_another_hand():
    gifu = ExperienceBase(np.zeros((2, 2)), ["FF_J2", "FF_J3"], "database")
    with pytest.raises(ValueError, match="not joints of hand 'shadow'"):
        make(gifu)


def test_closing_steer_never_opens_and_keeps_spread_and_rotation_joints():
    names = LAYOUT.finger_joints
    posture = np.zeros(len(names))
    posture[names.index("MFJ3")] = 0.3  # flexes further: approached
    posture[names.index("THJ5")] = -1.0  # rotation: not steered by the match
    posture[names.index("FFJ4")] = 0.3  # spread: not steered by the match
    pre = {"THJ5": -0.2, "FFJ2": 0.4}  # FFJ2 pre-flexed beyond the match (0): never opened
    ctl = make(
        ExperienceBase(posture[None], names),
        ControllerConfig(pregrasp=pre, approach_speed=0.6, steer_before_contact=True),
    )
    t = ctl.step(ctl.pregrasp.copy(), [])
    for _ in range(40):
        t = ctl.step(t, [])
        assert t[col("FFJ2")] >= 0.4 and t[col("THJ5")] == pytest.approx(-0.2) and t[col("FFJ4")] == 0.0
    assert t[col("MFJ3")] > 0.3  # reached the match, then closed further


def test_blend_steer_closes_at_least_as_fast_as_the_heuristic_and_faster_towards_the_match():
    names = LAYOUT.finger_joints
    posture = np.zeros(len(names))
    posture[names.index("MFJ2")] = 1.0
    cfg = ControllerConfig(pregrasp={}, approach_speed=3.0, steer="blend", steer_before_contact=True)
    blend, plain = make(ExperienceBase(posture[None], names), cfg), make(config=cfg)
    tb = tp = blend.pregrasp.copy()
    for _ in range(10):
        tb, tp = blend.step(tb, []), plain.step(tp, [])
    assert np.all(tb[blend.closing_mask] >= tp[plain.closing_mask] - 1e-12)
    assert tb[col("MFJ2")] > tp[col("MFJ2")] + 0.1  # pulled towards the match at approach_speed


def test_unknown_steer_mode_is_refused():
    with pytest.raises(ValueError, match="steer"):
        ControllerConfig(steer="sideways")


def test_without_steering_before_contact_phase_b_is_tactile_and_contacts_start_matching():
    names = LAYOUT.finger_joints
    posture = np.zeros(len(names))
    posture[names.index("MFJ2")] = 1.5
    cfg = ControllerConfig(pregrasp={}, approach_speed=3.0, rematch_cycles=0, steer_before_contact=False)
    late, plain = make(ExperienceBase(posture[None], names), cfg), make(config=cfg)
    tl = tp = late.pregrasp.copy()
    for _ in range(10):
        tl, tp = late.step(tl, []), plain.step(tp, [])
    np.testing.assert_array_equal(tl, tp)  # phase B: same targets as without experience
    assert late.n_matches == 0
    tl = late.step(tl, ["FF_distal"])  # first contact: the PCP match steers the free fingers
    assert late.n_matches == 1
    for _ in range(5):
        tl = late.step(tl, ["FF_distal"])
    assert tl[col("MFJ2")] > tp[col("MFJ2")] + 0.2


def test_synchronous_approach_brings_every_joint_to_the_match_in_the_same_cycle():
    names = LAYOUT.finger_joints
    posture = np.zeros(len(names))
    posture[names.index("MFJ3")], posture[names.index("FFJ2")] = 0.4, 0.1
    cfg = ControllerConfig(pregrasp={}, approach_speed=0.6, synchronous_approach=True, steer_before_contact=True)
    ctl = make(ExperienceBase(posture[None], names), cfg)
    t = ctl.step(ctl.pregrasp.copy(), [])
    mf, ff = [t[col("MFJ3")]], [t[col("FFJ2")]]
    for _ in range(50):
        t = ctl.step(t, [])
        mf.append(t[col("MFJ3")])
        ff.append(t[col("FFJ2")])
    mf, ff = np.array(mf), np.array(ff)
    arrive_mf, arrive_ff = np.argmax(mf >= 0.4 - 1e-9), np.argmax(ff >= 0.1 - 1e-9)
    assert arrive_mf == arrive_ff == 39  # 0.4 rad at 0.6 rad/s, 60 Hz: 40 cycles (from cycle 0)
    np.testing.assert_allclose(ff[:arrive_ff], mf[:arrive_mf] / 4, atol=1e-9)  # on the straight line to the match
