"""Headless evaluation of the manipulation controllers (docs/manipulation.md).

The plain controller classes drive the plain :class:`~handflow.plugins.simulator.simulation.Simulation`
(no Zenoh): a control step every ``physics_hz / control_hz`` physics steps.

- Cap turning: :class:`GraspByNavigation` per cap radius; cap rotation per motion cycle (deg,
  positive = the demonstrations' turning direction) and the radius it found.
- Ball swapping: open loop vs closed loop on the same manifold, calm and under two disturbances
  of the balls scene: ``turns`` (the thesis' scenario: the ball pair is turned back against its
  travel by ``turn_deg`` — a ball pushed back along its path — at times that fall at the same
  hand phase of the open loop) and ``pushes`` (a velocity kick against the travel).
  Observations come from the camera + colour-blob tracker (``camera=True``) or, documented
  choice for ``--quick``, from the ideal tracker (:func:`ideal_balls`: ground-truth positions
  projected with the same camera and normalised to the marks).  Swaps are counted on the
  ground-truth palm-plane positions with :mod:`handflow.plugins.simulator.metrics` (net half-turns of the
  ball pair).  **Recovery** (documented definition, :func:`recoveries`): a disturbance at ``t``
  is recovered when, within ``recovery_within_s`` (10 s) after it, there is a window of
  ``recovery_window_s`` (4 s) in which the pair progresses at least ``recovery_fraction`` (50 %)
  of the same controller's calm swap rate.
- Control-loop latency: observation → command through :class:`~.nodes.ClosedLoopNode` code.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from handflow.framework.messages import Points2D
from handflow.framework.testing import NodeHarness
from handflow.plugins.simulator.metrics import swap_progress, swaps_per_minute
from handflow.plugins.simulator.simulation import Simulation
from handflow.plugins.tracker.blobs import BallTracker, normalise_points

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


def cap_turning(
    manifold: ManipulationManifold, radius_cm: float, settings: CapSettings = CapSettings(), seed: int = 0
) -> dict:
    """Grasp by navigation then turn ``settings.cycles`` cycles; returns deg_per_cycle (net rotation
    over all cycles / cycles), per_cycle_deg (rotation of each cycle: the first one carries the
    grasp's settling transient, see docs/manipulation.md) and found_radius (the frozen latent
    radius: cm on a constructed manifold, latent units on a learned one)."""
    t_dim = manifold.time_dim
    lo, hi = manifold.range(t_dim)
    delta = (hi - lo) / (settings.cycle_s * settings.control_hz)
    per_control = int(round(settings.physics_hz / settings.control_hz))
    r_lo, r_hi = manifold.range(1 - t_dim)
    ctl = GraspByNavigation(
        manifold,
        delta,
        settings.radius_step_fraction * (r_hi - r_lo),
        approach_steps=int(settings.approach_s * settings.control_hz),
    )
    turning_steps = int(round(settings.cycles * (hi - lo) / delta))
    with Simulation("shadow", "cap", {"radius": radius_cm / 100.0}, seed=seed, physics_hz=settings.physics_hz) as sim:
        max_grasp = int((settings.approach_s + settings.max_closing_s) * settings.control_hz)
        for _ in range(max_grasp):
            x = ctl.update(touching_fingers(sim.contacts()))
            sim.set_targets(manifold.joint_names, ctl.posture(x))
            sim.step(per_control)
            if ctl.state == TURNING:
                break
        angles = [sim.scene_state()["cap_angle"]]
        for step in range(1, turning_steps + 1):
            x = ctl.update(())
            sim.set_targets(manifold.joint_names, ctl.posture(x))
            sim.step(per_control)
            if step * settings.cycles // turning_steps > len(angles) - 1:
                angles.append(sim.scene_state()["cap_angle"])
    per_cycle = np.degrees(np.diff(angles))
    return {
        "deg_per_cycle": float(per_cycle.sum() / settings.cycles),
        "per_cycle_deg": per_cycle.tolist(),
        "found_radius": float(ctl.radius),
        "grasp_complete": bool(ctl.grasp_complete),
    }


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
    """Ball-swap run settings (closed loop: ``k`` steps of ``delta``, ``mask`` and ``tolerance`` of
    :class:`ClosedLoopController`; both: ``period_s`` per latent period at the control rate;
    disturbances: ``push_times_s`` at ``push_speed`` m/s, ``turn_times_s`` by ``turn_deg``,
    ``hold_times_s`` for ``hold_s`` s)."""

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
    turn_times_s: tuple[float, ...] = ()
    turn_deg: float = 90.0
    hold_times_s: tuple[float, ...] = ()
    hold_s: float = 1.0
    seed: int = 0
    mask: str = "ball1"
    tolerance: float = 0.05
    lag: float = 0.5
    max_error: float = 0.1


def ball_swap(manifold: ManipulationManifold, closed_loop: bool, settings: BallSettings) -> dict:
    """One run; returns swaps_per_min, times (s) and swap progress (signed swaps, see
    :func:`handflow.plugins.simulator.metrics.swap_progress`) per control step."""
    t_lo, t_hi = manifold.range(manifold.time_dim)
    delta = (t_hi - t_lo) / (settings.period_s * settings.control_hz)
    per_control = int(round(settings.physics_hz / settings.control_hz))
    per_camera = max(int(round(settings.control_hz / settings.camera_hz)), 1)
    tracker = BallTracker()
    options = {
        "pushes": [[t, settings.push_speed] for t in settings.push_times_s],
        "turns": [[t, settings.turn_deg] for t in settings.turn_times_s],
        "holds": [[t, settings.hold_s] for t in settings.hold_times_s],
    }
    with Simulation("gifu", "balls", options, seed=settings.seed, physics_hz=settings.physics_hz) as sim:
        open_ctl = OpenLoopController(manifold, [t_lo], delta)
        closed = ClosedLoopController(
            manifold, settings.k, delta, settings.mask, settings.tolerance, settings.lag, settings.max_error
        )
        plan: list = []
        last = None
        positions, times = [], []
        for step in range(int(settings.duration_s * settings.control_hz)):
            if closed_loop and step % per_camera == 0:
                if settings.camera:
                    res = tracker.update(sim.render(settings.width, settings.height))
                    balls, valid = res.balls, res.balls_valid
                else:
                    balls, valid = ideal_balls(sim, settings.width, settings.height), [True, True]
                out = closed.update(balls, valid, last)
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
    return {
        "swaps_per_min": swaps_per_minute(times, P[:, 0], P[:, 1]),
        "times": times,
        "progress": swap_progress(P[:, 0], P[:, 1]),
    }


def recoveries(
    times,
    progress,
    disturbances_s,
    calm_swaps_per_min: float,
    within_s: float = 10.0,
    window_s: float = 4.0,
    fraction: float = 0.5,
    direction: float = 1.0,
) -> int:
    """How many disturbances were recovered: within ``within_s`` after the disturbance some
    ``window_s`` window shows swap progress (in ``direction``, ±1) of at least ``fraction`` of the
    calm rate.  A calm rate of 0 (a controller that never swaps) recovers nothing."""
    t, prog = np.asarray(times, dtype=float), direction * np.asarray(progress, dtype=float)
    need = fraction * abs(calm_swaps_per_min) / 60.0 * window_s
    if need <= 0:
        return 0
    count = 0
    for td in disturbances_s:
        starts = t[(t >= td) & (t <= td + within_s - window_s)]
        gain = np.interp(starts + window_s, t, prog) - np.interp(starts, t, prog)
        count += int(np.any(gain >= need))
    return count


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
    """What ``handflow evaluate manipulation`` runs (``quick()`` is the < 2 min variant).

    Disturbances every ``disturb_every_s`` starting at ``first_disturbance_s``: with a 2 s hand
    cycle (period_s = 4 s per ball period = two hand cycles) every disturbance falls at the same
    open-loop hand phase, a quarter into the cycle (the rake stroke)."""

    radii_cm: tuple[float, ...] = TRAINING_RADII_CM + INTERMEDIATE_RADII_CM
    cap: CapSettings = field(default_factory=CapSettings)
    balls: BallSettings = field(default_factory=BallSettings)
    first_disturbance_s: float = 10.5
    disturb_every_s: float = 15.0

    @classmethod
    def quick(cls) -> EvalPlan:
        return cls(cap=CapSettings(cycles=2), balls=BallSettings(duration_s=30.0, camera=False), disturb_every_s=12.0)

    def disturbances(self) -> tuple[float, ...]:
        end = self.balls.duration_s - 1e-9
        return tuple(np.arange(self.first_disturbance_s, end, self.disturb_every_s).tolist())


DISTURBANCE_CLASSES = {
    "turn_back": ("turn_times_s", ""),
    "push": ("push_times_s", "_pushed"),
    "hold": ("hold_times_s", "_held"),
}
"""Disturbance class → (:class:`BallSettings` field of its times, key suffix in the per-controller rows)."""

BALL_CONTROLLERS = {"open_loop": (False, None), "closed_loop": (True, None), "closed_loop_thesis": (True, 0.0)}
"""Evaluation name → (closed loop?, tolerance override: None = the plan's, 0 = pure projection)."""


def ball_swap_report(manifold: ManipulationManifold, plan: EvalPlan, progress=lambda line: None) -> dict:
    """Per controller: calm rate, rate and recoveries under turn-backs (``swaps_per_min_disturbed``,
    ``recoveries``, the thesis scenario), pushes (``…_pushed``) and holds (``…_held``)."""
    times = plan.disturbances()
    out = {}
    for name, (closed, tolerance) in BALL_CONTROLLERS.items():
        base = BallSettings(
            **{**plan.balls.__dict__, "tolerance": plan.balls.tolerance if tolerance is None else tolerance}
        )
        calm = ball_swap(manifold, closed, base)
        direction = 1.0 if calm["progress"][-1] >= 0 else -1.0
        row = {"swaps_per_min": calm["swaps_per_min"]}
        for field_name, key in DISTURBANCE_CLASSES.values():
            run = ball_swap(manifold, closed, BallSettings(**{**base.__dict__, field_name: times}))
            row[f"swaps_per_min_disturbed{key}"] = run["swaps_per_min"]
            row[f"recoveries{key}"] = recoveries(
                run["times"], run["progress"], times, calm["swaps_per_min"], direction=direction
            )
        row["disturbances"] = len(times)
        out[name] = row
        progress(f"ball swap {name}: {row}")
    return out


def disturbance_classes(rows: dict) -> dict:
    """``{class: {controller: {"rate", "recovered_share"}}}`` from the rows of :func:`ball_swap_report`."""
    return {
        cls: {
            name: {
                "rate": row[f"swaps_per_min_disturbed{key}"],
                "recovered_share": row[f"recoveries{key}"] / max(row["disturbances"], 1),
            }
            for name, row in rows.items()
        }
        for cls, (_, key) in DISTURBANCE_CLASSES.items()
    }


def evaluate(
    constructed: ManipulationManifold,
    learned: ManipulationManifold,
    balls: ManipulationManifold,
    plan: EvalPlan,
    ball_path,
    progress=lambda line: None,
) -> dict:
    """The JSON of ``handflow evaluate manipulation``."""
    cap = {}
    for key, manifold in (("cap_turning", constructed), ("cap_turning_learned", learned)):
        cap[key] = {}
        for r in sorted(plan.radii_cm):
            res = cap[key][f"{r:g}"] = cap_turning(manifold, r, plan.cap)
            progress(f"{key} r={r:g} cm: {res['deg_per_cycle']:.1f} deg/cycle, found radius {res['found_radius']:.2f}")
    report = learned.model.provenance_
    rows = ball_swap_report(balls, plan, progress)
    return {
        **cap,
        "ball_swap": rows,
        "disturbance_classes": disturbance_classes(rows),
        "radius_spearman": report.get("spearman"),
        "radius_separation": report.get("separation"),
        "loop_latency_ms": loop_latency_ms(ball_path, k=plan.balls.k),
    }
