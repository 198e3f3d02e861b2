"""Headless evaluation of the manipulation controllers (issue 6 "Measure"; production.md §4).

The plain controller classes drive the plain :class:`~plugins.simulator.simulation.Simulation`
(no Zenoh): a control step every ``physics_hz / control_hz`` physics steps.

- Cap turning: :class:`GraspByNavigation` per cap radius; cap rotation per motion cycle (deg,
  positive = the demonstrations' turning direction) and the radius it found.
- Ball swapping: open loop vs closed loop on the same manifold, without and with pushes.
  Observations come from the camera + colour-blob tracker (``camera=True``) or, documented
  choice for ``--quick``, from the ideal tracker (:func:`ideal_balls`: ground-truth positions
  projected with the same camera and normalised to the marks).  Pushes are the balls scene's
  ``pushes`` option; swaps are counted on the ground-truth palm-plane positions with
  :mod:`plugins.simulator.metrics` (net half-turns of the ball pair); a push "is recovered" when
  the next swap completes within ``recovery_window_s`` after it.
- Control-loop latency: observation → command through :class:`~.nodes.ClosedLoopNode` code.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from framework.messages import Points2D
from framework.testing import NodeHarness
from plugins.simulator.metrics import swap_times, swaps_per_minute
from plugins.simulator.simulation import Simulation
from plugins.tracker.blobs import BallTracker, normalise_points

from .closed_loop import ClosedLoopController
from .feedback_init import TURNING, GraspByNavigation, touching_fingers
from .manifold_file import ManipulationManifold
from .nodes import ClosedLoopNode
from .open_loop import OpenLoopController

TRAINING_RADII_CM = (1.5, 2.0, 2.5, 3.0, 3.5)
INTERMEDIATE_RADII_CM = (1.75, 2.25, 2.75, 3.25)


@dataclass
class CapSettings:
    """Cap-turning run: motion cycle duration, cycles turned, closing speed (fraction of the latent
    radius range per control step: 0.005 = 0.01 cm on the constructed 1.5–3.5 cm axis), rates."""

    cycle_s: float = 2.0
    cycles: int = 3
    radius_step_fraction: float = 0.005
    approach_s: float = 1.0
    control_hz: float = 30.0
    physics_hz: float = 240.0
    max_closing_s: float = 10.0


def cap_turning(manifold: ManipulationManifold, radius_cm: float, settings: CapSettings = CapSettings(),
                seed: int = 0) -> dict:
    """Grasp by navigation then turn ``settings.cycles`` cycles; returns deg_per_cycle and
    found_radius (the frozen latent radius: cm on a constructed manifold, latent units on a
    learned one)."""
    t_dim = manifold.time_dim
    lo, hi = manifold.range(t_dim)
    delta = (hi - lo) / (settings.cycle_s * settings.control_hz)
    per_control = int(round(settings.physics_hz / settings.control_hz))
    r_lo, r_hi = manifold.range(1 - t_dim)
    ctl = GraspByNavigation(manifold, delta, settings.radius_step_fraction * (r_hi - r_lo),
                            approach_steps=int(settings.approach_s * settings.control_hz))
    turning_steps = int(round(settings.cycles * (hi - lo) / delta))
    with Simulation("shadow", "cap", {"radius": radius_cm / 100.0}, seed=seed,
                    physics_hz=settings.physics_hz) as sim:
        max_grasp = int((settings.approach_s + settings.max_closing_s) * settings.control_hz)
        for _ in range(max_grasp):
            x = ctl.update(touching_fingers(sim.contacts()))
            sim.set_targets(manifold.joint_names, manifold.posture(x))
            sim.step(per_control)
            if ctl.state == TURNING:
                break
        start = sim.scene_state()["cap_angle"]
        for _ in range(turning_steps):
            x = ctl.update(())
            sim.set_targets(manifold.joint_names, manifold.posture(x))
            sim.step(per_control)
        turned = sim.scene_state()["cap_angle"] - start
    return {"deg_per_cycle": float(np.degrees(turned) / settings.cycles),
            "found_radius": float(ctl.radius), "grasp_complete": bool(ctl.grasp_complete)}


# -- ball swapping -----------------------------------------------------------------------------
def ideal_balls(sim: Simulation, width: int = 240, height: int = 180) -> np.ndarray:
    """Ground-truth ball positions (2, 2) normalised to the marks exactly as the tracker does."""
    scene = sim.scene
    cam = scene.camera()
    balls_px = cam.project(scene.ball_positions(sim.client), width, height)
    marks_px = cam.project(scene.mark_positions(), width, height)
    return normalise_points(balls_px, marks_px[0], marks_px[1])


@dataclass
class BallSettings:
    """Ball-swap run settings (closed loop: ``k`` steps of ``delta``; both: ``period_s`` per
    latent period at the control rate)."""

    duration_s: float = 120.0
    period_s: float = 4.0
    k: int = 5
    control_hz: float = 20.0
    camera_hz: float = 10.0
    physics_hz: float = 240.0
    camera: bool = True
    width: int = 240
    height: int = 180
    push_times_s: tuple[float, ...] = ()
    push_speed: float = 0.3
    recovery_window_s: float = 8.0
    seed: int = 0
    mask: str = "ball1"
    prior_weight: float = 100.0


def ball_swap(manifold: ManipulationManifold, closed_loop: bool, settings: BallSettings) -> dict:
    """One run; returns swaps_per_min, swaps, recoveries, pushes."""
    t_lo, t_hi = manifold.range(manifold.time_dim)
    delta = (t_hi - t_lo) / (settings.period_s * settings.control_hz)
    per_control = int(round(settings.physics_hz / settings.control_hz))
    per_camera = max(int(round(settings.control_hz / settings.camera_hz)), 1)
    tracker = BallTracker()
    pushes = [[t, settings.push_speed] for t in settings.push_times_s]
    with Simulation("gifu", "balls", {"pushes": pushes}, seed=settings.seed,
                    physics_hz=settings.physics_hz) as sim:
        open_ctl = OpenLoopController(manifold, [t_lo], delta)
        closed = ClosedLoopController(manifold, settings.k, delta, settings.mask,
                                      settings.prior_weight)
        plan: list = []
        last = None
        positions, times = [], []
        for step in range(int(settings.duration_s * settings.control_hz)):
            if closed_loop and step % per_camera == 0:
                if settings.camera:
                    res = tracker.update(sim.render(settings.width, settings.height))
                    out = closed.update(res.balls, res.balls_valid, last)
                else:
                    out = closed.update(ideal_balls(sim, settings.width, settings.height),
                                        [True, True], last)
                if out is not None:
                    plan = list(zip(out[1], out[2]))
            if closed_loop:
                if plan:
                    last, q = plan.pop(0)
                    sim.set_targets(manifold.joint_names, q)
            else:
                sim.set_targets(manifold.joint_names, open_ctl.step()[1])
            sim.step(per_control)
            positions.append(sim.scene.palm_plane_positions(sim.client))
            times.append(sim.time)
    P, times = np.asarray(positions), np.asarray(times)
    done = swap_times(times, P[:, 0], P[:, 1])
    recovered = sum(int(np.any((done > t) & (done <= t + settings.recovery_window_s)))
                    for t in settings.push_times_s)
    return {"swaps_per_min": swaps_per_minute(times, P[:, 0], P[:, 1]), "swaps": int(done.size),
            "recoveries": recovered, "pushes": len(settings.push_times_s)}


def loop_latency_ms(manifold_path, n: int = 200, k: int = 5, seed: int = 0) -> list[float]:
    """Median and p99 (ms) of observation → command through the closed-loop node's code."""
    h = NodeHarness(ClosedLoopNode, {"manifold": str(manifold_path), "k": k}).setup()
    man = h.node.manifold
    rng = np.random.default_rng(seed)
    obs = man.model.Y_[rng.integers(0, len(man.model.Y_), n)][:, man.ball_index].reshape(n, 2, 2)
    lat = []
    for pts in obs:
        msg = Points2D(points=pts, valid=[True, True], ids=[0, 1])
        t0 = time.perf_counter()
        h.send("balls", msg)
        lat.append(time.perf_counter() - t0)
    ms = np.asarray(lat) * 1e3
    return [float(np.median(ms)), float(np.percentile(ms, 99))]


@dataclass
class EvalPlan:
    """What ``handflow evaluate manipulation`` runs (``quick()`` is the < 2 min variant)."""

    radii_cm: tuple[float, ...] = TRAINING_RADII_CM + INTERMEDIATE_RADII_CM
    cap: CapSettings = field(default_factory=CapSettings)
    balls: BallSettings = field(default_factory=BallSettings)
    push_every_s: float = 15.0

    @classmethod
    def quick(cls) -> "EvalPlan":
        return cls(cap=CapSettings(cycles=1),
                   balls=BallSettings(duration_s=30.0, camera=False), push_every_s=10.0)


def evaluate(constructed: ManipulationManifold, learned: ManipulationManifold,
             balls: ManipulationManifold, plan: EvalPlan, ball_path,
             progress=lambda line: None) -> dict:
    """The JSON of ``handflow evaluate manipulation``."""
    cap = {}
    for key, manifold in (("cap_turning", constructed), ("cap_turning_learned", learned)):
        cap[key] = {}
        for r in sorted(plan.radii_cm):
            res = cap[key][f"{r:g}"] = cap_turning(manifold, r, plan.cap)
            progress(f"{key} r={r:g} cm: {res['deg_per_cycle']:.1f} deg/cycle, found radius "
                     f"{res['found_radius']:.2f}")
    pushes = tuple(np.arange(plan.push_every_s, plan.balls.duration_s - 1e-9, plan.push_every_s))
    swap = {}
    for name, closed, prior in (("open_loop", False, plan.balls.prior_weight),
                                ("closed_loop", True, plan.balls.prior_weight),
                                ("closed_loop_no_prior", True, 0.0)):
        settings = BallSettings(**{**plan.balls.__dict__, "prior_weight": prior})
        calm = ball_swap(balls, closed, settings)
        disturbed = ball_swap(balls, closed, BallSettings(**{**settings.__dict__,
                                                             "push_times_s": pushes}))
        swap[name] = {"swaps_per_min": calm["swaps_per_min"],
                      "swaps_per_min_disturbed": disturbed["swaps_per_min"],
                      "recoveries": disturbed["recoveries"], "pushes": disturbed["pushes"]}
        progress(f"ball swap {name}: {swap[name]}")
    report = learned.model.provenance_
    return {**cap, "ball_swap": swap,
            "radius_spearman": report.get("spearman"), "radius_separation": report.get("separation"),
            "loop_latency_ms": loop_latency_ms(ball_path, k=plan.balls.k)}
