"""Plain controller classes (docs/manipulation.md) on synthetic manifolds."""

import numpy as np
import pytest

from handflow.plugins.manipulation import ClosedLoopController, GraspByNavigation, OpenLoopController
from handflow.plugins.manipulation.feedback_init import CLOSING, TURNING, flexion, open_side
from handflow.plugins.manipulation.latent_time import LatentClock
from tests.manipulation.synthetic import posture


def test_open_loop_output_is_f_along_the_commanded_path_and_resets_on_a_constructed_axis(cap_manifold):
    lo, hi = cap_manifold.range(0)
    delta = (hi - lo) / 20.5
    ctl = OpenLoopController(cap_manifold, [lo, 2.25], delta)
    xs, qs = zip(*[ctl.step() for _ in range(30)])
    xs, qs = np.array(xs), np.array(qs)
    assert np.allclose(xs[:, 1], 2.25)
    assert np.allclose(qs, cap_manifold.posture(xs))
    assert np.all(xs[:, 0] <= hi) and xs[20, 0] == lo  # jumped back after passing the end
    assert np.allclose(np.diff(xs[:20, 0]), delta)
    assert ctl.cycles == 1


def test_open_loop_wraps_smoothly_on_a_periodic_axis(ball_manifold):
    sign = ball_manifold.time_sign
    ctl = OpenLoopController(ball_manifold, [3.0 if sign > 0 else 0.1], 0.1)
    xs = np.array([ctl.step()[0][0] for _ in range(10)])
    steps = np.mod(sign * np.diff(xs), np.pi)
    assert np.allclose(steps, 0.1) and abs(ctl.cycles) == 1 and np.all((xs >= 0) & (xs < np.pi))


def test_time_runs_in_the_direction_of_the_demonstrations(ball_manifold):
    from handflow.plugins.manipulation import ManipulationManifold

    model, sign = ball_manifold.model, ball_manifold.time_sign
    mirrored = type(model).from_latents(
        model.Y_, np.pi - model.latents_, model.sequence_ids_, latent=model.latent, lambda_pvar=0.0
    )
    flipped = ManipulationManifold(mirrored, ball_manifold.names, "gifu", ["time"], "ball_swap")
    assert flipped.time_sign == -sign
    x0 = 1.0
    ctl = OpenLoopController(flipped, [np.pi - x0], 0.05)  # same posture as x0 on the original
    for _ in range(3):
        ctl.step()
    reached = flipped.observation(ctl.x)
    forward = ball_manifold.observation(np.array([x0 + 0.15 * sign]))
    backward = ball_manifold.observation(np.array([x0 - 0.15 * sign]))
    assert np.linalg.norm(reached - forward) < 0.1 * np.linalg.norm(reached - backward)


def test_open_loop_rejects_a_start_of_the_wrong_size(cap_manifold):
    with pytest.raises(ValueError, match="2 coordinates"):
        OpenLoopController(cap_manifold, [0.5], 0.01)


def test_latent_clock_reset_and_lookahead():
    clock = LatentClock(0.0, 1.0, periodic=False, start=0.9)
    assert np.allclose(clock.ahead([0.05, 0.2]), [0.95, 0.1])
    assert clock.advance(0.2) == 0.0 and clock.cycles == 1


def _touching_model(manifold, true_radius):
    """Fingers touch when the commanded closure reaches the closure of the true radius."""

    def touching(x):
        ref = np.array([x[0], true_radius])
        return {"TH", "FF", "MF"} if flexion(manifold, x) >= flexion(manifold, ref) - 1e-9 else set()

    return touching


@pytest.mark.parametrize("true_radius", [1.75, 2.5, 3.25])
def test_grasp_by_navigation_finds_the_radius_then_turns(cap_manifold, true_radius):
    assert open_side(cap_manifold) == pytest.approx(3.5)  # the more open border
    ctl = GraspByNavigation(cap_manifold, delta=0.02, radius_step=0.01, approach_steps=3)
    touching = _touching_model(cap_manifold, true_radius)
    x = ctl.x.copy()
    assert x[1] == pytest.approx(3.5)
    for _ in range(400):
        x = ctl.update(touching(x))
        if ctl.state == TURNING:
            break
    assert ctl.grasp_complete and abs(ctl.radius - true_radius) < 0.05
    t_before = x[0]
    x = ctl.update(set())  # contacts no longer matter
    assert x[1] == ctl.radius and x[0] == pytest.approx(t_before + 0.02)


@pytest.mark.parametrize("overshoot, limit", [(0.0, 1.5), (0.25, 1.0)])
def test_grasp_by_navigation_stops_at_its_limit_without_contact(cap_manifold, overshoot, limit):
    ctl = GraspByNavigation(cap_manifold, delta=0.02, radius_step=0.2, approach_steps=0, overshoot=overshoot)
    for _ in range(30):
        ctl.update(set())
    assert ctl.state == TURNING and not ctl.grasp_complete and ctl.radius == pytest.approx(limit)


def _turn_cycle(ctl, steps, gripped):
    """One cycle of ``steps`` turning updates, the fingers touching in the first ``gripped``."""
    for k in range(steps):
        ctl.update({"TH", "FF", "MF"} if k < gripped else set())


@pytest.mark.parametrize("regrasp", [False, True])
def test_grasp_by_navigation_regrasps_when_the_grip_time_halves(cap_manifold, regrasp):
    lo, hi = cap_manifold.range(0)
    steps = 20
    ctl = GraspByNavigation(cap_manifold, delta=(hi - lo) / steps, radius_step=0.01, approach_steps=0, regrasp=regrasp)
    touching = _touching_model(cap_manifold, 2.5)
    while ctl.state != TURNING:
        ctl.update(touching(ctl.x))
    _turn_cycle(ctl, steps, 8)  # the reference: 8 steps of grip per cycle
    _turn_cycle(ctl, steps, 4)  # half of it: still a grip
    assert ctl.state == TURNING and ctl.regrasps == 0
    _turn_cycle(ctl, steps, 3)  # below half: the cap is lost
    assert (ctl.state == CLOSING) == regrasp and ctl.regrasps == int(regrasp)
    if regrasp:  # closing again, the time held, until a smaller cap is touched
        t_held = ctl.x[0]
        touching = _touching_model(cap_manifold, 1.75)
        while ctl.state != TURNING:
            assert ctl.update(touching(ctl.x))[0] == t_held
        assert abs(ctl.radius - 1.75) < 0.05 and ctl.grasp_complete


def test_regrasp_fraction_must_lie_between_zero_and_one(cap_manifold):
    with pytest.raises(ValueError, match="regrasp_fraction"):
        GraspByNavigation(cap_manifold, delta=0.02, radius_step=0.01, regrasp=True, regrasp_fraction=1.5)


def test_postures_beyond_the_radius_border_continue_the_trend(cap_manifold):
    lo, hi = cap_manifold.range(1)
    t = 0.4
    X = np.array([[t, lo - 0.3], [t, lo], [t, lo + 0.5], [t, hi], [t, hi - 0.5], [t, hi + 0.2], [t, 2.5]])
    plain = cap_manifold.posture(X)
    ext = cap_manifold.posture(X, extrapolate=True)
    assert np.allclose(ext[1:5], plain[1:5]) and np.allclose(ext[6], plain[6])  # inside: f
    low, high = (plain[1] - plain[2]) / 0.5, (plain[3] - plain[4]) / 0.5  # secants, 0.5 cm
    assert np.allclose(ext[0], plain[1] + 0.3 * low) and np.allclose(ext[5], plain[3] + 0.2 * high)
    # kernel regression flattens out beyond the border; the extrapolation keeps the trend
    assert np.linalg.norm(plain[0] - plain[1]) < 0.5 * np.linalg.norm(ext[0] - ext[1])
    ctl = GraspByNavigation(cap_manifold, delta=0.02, radius_step=0.01)
    assert np.allclose(ctl.posture(X[0]), ext[0])


def test_grasp_by_navigation_starts_in_the_closed_phase(cap_manifold):
    ctl = GraspByNavigation(cap_manifold, delta=0.02, radius_step=0.01)
    assert ctl.state != CLOSING
    lo, hi = cap_manifold.range(0)
    grid = np.c_[np.linspace(lo, hi, 200), np.full(200, 3.5)]
    assert flexion(cap_manifold, ctl.x) >= 0.9 * flexion(cap_manifold, grid).max()


def test_posture_projection_recovers_the_radius(cap_manifold):
    from handflow.plugins.manipulation.feedback_init import latent_from_grasp

    y = posture([0.45], 2.5)[0]
    x = latent_from_grasp(cap_manifold, dict(zip(cap_manifold.names, y)))
    assert abs(x[1] - 2.5) < 0.2


def _circ(a, b, period):
    d = np.mod(a - b, period)
    return np.minimum(d, period - d)


def test_closed_loop_phase_estimate_uses_the_better_ball_assignment(ball_manifold):
    ctl = ClosedLoopController(ball_manifold, k=4, delta=0.05)
    model = ball_manifold.model
    swapped = []
    for x, o in zip(model.latents_[::7], model.Y_[::7]):
        for pts in (o[4:].reshape(2, 2), o[4:].reshape(2, 2)[::-1]):  # both orders
            est = ctl.estimate(pts, [True, True])
            swapped.append(est.swapped)
            # identical balls: phases x and x + π/2 show the same observation
            assert _circ(est.x[0], x[0], np.pi / 2) < 0.08
            assert np.allclose(ball_manifold.posture(est.x), o[:4], atol=0.1)
    assert any(swapped) and not all(swapped)


def _balls_at(manifold, x):
    return manifold.observation(np.array([x]))[4:].reshape(2, 2)


def test_closed_loop_keeps_the_commanded_phase_while_the_balls_agree(ball_manifold):
    ctl = ClosedLoopController(ball_manifold, tolerance=0.05, lag=0.3)
    est = ctl.estimate(_balls_at(ball_manifold, 1.0), [True, True], prior=np.array([1.2]))
    assert est.x[0] == pytest.approx(1.2)  # within the lag: the motion goes on
    pure = ClosedLoopController(ball_manifold, tolerance=0.0).estimate(
        _balls_at(ball_manifold, 1.0), [True, True], prior=np.array([1.2])
    )
    assert _circ(pure.x[0], 1.0, np.pi / 2) < 0.03  # thesis: the projection alone


def test_closed_loop_jumps_back_to_the_phase_of_a_pushed_back_ball(ball_manifold):
    ctl = ClosedLoopController(ball_manifold, tolerance=0.02, lag=0.3)
    back = 1.0 - 0.6 * ball_manifold.time_sign  # the balls are 0.6 behind the hand
    est = ctl.estimate(_balls_at(ball_manifold, back), [True, True], prior=np.array([1.0]))
    assert _circ(est.x[0], back, np.pi / 2) < 0.1 and _circ(est.x[0], 1.0, np.pi) > 0.4


def test_after_a_jump_the_closed_loop_keeps_its_phase_for_the_refractory_span(ball_manifold):
    sign = ball_manifold.time_sign
    back = 1.0 - 0.6 * sign
    guarded = ClosedLoopController(ball_manifold, tolerance=0.02, lag=0.3, refractory=1.0)
    free = ClosedLoopController(ball_manifold, tolerance=0.02, lag=0.3)
    for ctl in (guarded, free):
        first = ctl.estimate(_balls_at(ball_manifold, back), [True, True], prior=np.array([1.0]))
        assert _circ(first.x[0], back, np.pi / 2) < 0.1  # both jump the first time
    # the replayed stroke has gone 0.5 on; the balls still trail it by 0.6
    prior = np.array([first.x[0] + 0.5 * sign])
    balls = _balls_at(ball_manifold, first.x[0] - 0.1 * sign)
    assert guarded.estimate(balls, [True, True], prior=prior).x[0] == pytest.approx(prior[0])
    assert free.estimate(balls, [True, True], prior=prior).x[0] != pytest.approx(prior[0])
    # once the hand has gone past the refractory span, the balls decide again
    later = np.array([first.x[0] + 1.2 * sign])
    assert guarded.estimate(_balls_at(ball_manifold, later[0] - 0.6 * sign), [True, True], prior=later).x[0] != (
        pytest.approx(later[0])
    )


def test_closed_loop_keeps_the_commanded_phase_when_the_balls_are_off_the_manifold(ball_manifold):
    far = np.array([[3.0, 3.0], [-3.0, 3.0]])
    loose = ClosedLoopController(ball_manifold, tolerance=0.05, lag=0.1, max_error=0.5)
    assert loose.estimate(far, [True, True], prior=np.array([1.0])).x[0] == pytest.approx(1.0)
    strict = ClosedLoopController(ball_manifold, tolerance=0.05, lag=0.1)  # no max_error
    assert strict.estimate(far, [True, True], prior=np.array([1.0])).x[0] != pytest.approx(1.0)


def test_closed_loop_rejects_negative_tolerances(ball_manifold):
    with pytest.raises(ValueError, match="tolerance, lag and refractory"):
        ClosedLoopController(ball_manifold, tolerance=-0.1)
    with pytest.raises(ValueError, match="tolerance, lag and refractory"):
        ClosedLoopController(ball_manifold, refractory=-1.0)


def test_closed_loop_plans_k_steps_ahead(ball_manifold):
    ctl = ClosedLoopController(ball_manifold, k=4, delta=0.05)
    X, targets = ctl.plan(np.array([3.1]))
    step = 0.05 * ball_manifold.time_sign
    assert np.allclose(X[:, 0], np.mod(3.1 + step * np.arange(1, 5), np.pi))
    assert np.allclose(targets, ball_manifold.posture(X))


def test_closed_loop_with_one_or_no_visible_ball(ball_manifold):
    ctl = ClosedLoopController(ball_manifold, k=2, delta=0.05)
    x, o = ball_manifold.model.latents_[5], ball_manifold.model.Y_[5]
    est = ctl.estimate(np.array([o[4:6], [np.nan, np.nan]]), [True, False])
    assert _circ(est.x[0], x[0], np.pi / 2) < 0.1
    assert ctl.update(np.full((2, 2), np.nan), [False, False]) is None
