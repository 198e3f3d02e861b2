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
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field

import numpy as np

from handflow.framework.messages import Points2D
from handflow.framework.testkit.harness import NodeHarness
from handflow.plugins.simulator.metrics import swap_progress, swaps_per_minute
from handflow.plugins.simulator.simulation import Simulation
from handflow.plugins.tracker.blobs import BallTracker, normalise_points

from .closed_loop import ClosedLoopController
from .disturbances import BALL_CLASSES, CAP_CLASSES, filled, recovery_times, schedule_times, summarise
from .feedback_init import CLOSING, TURNING, GraspByNavigation, touching_fingers
from .manifold_file import ManipulationManifold
from .nodes import ClosedLoopNode
from .open_loop import OpenLoopController

CAP_CONTROLLERS = ("open_loop", "feedback_init", "closed_loop")
"""Cap controllers of :func:`cap_turning`."""
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
    manifold: ManipulationManifold,
    radius_cm: float,
    settings: CapSettings = CapSettings(),
    seed: int = 0,
    scene_options: dict | None = None,
    controller: str = "feedback_init",
) -> dict:
    """Grasp by navigation then turn ``settings.cycles`` cycles; returns deg_per_cycle (net rotation
    over all cycles / cycles), per_cycle_deg (rotation of each cycle: the first one carries the
    grasp's settling transient, see docs/manipulation.md), found_radius (the frozen latent
    radius: cm on a constructed manifold, latent units on a learned one) and the turning phase's
    ``times`` (s) and cap ``turns`` (rotations, positive forward) per control step.
    ``scene_options``: extra cap-scene options (e.g. ``torques``, ``swaps``); ``controller``:
    ``feedback_init`` (grasp by navigation once), ``closed_loop`` (the same with ``regrasp``: the
    hand closes again when the grip time per cycle halves; ``regrasps`` counts those) or
    ``open_loop`` (no contact feedback — the radius is frozen at ``radius_cm``, a constructed
    manifold's cm axis, after the approach: the open loop of a user who knows the cap)."""
    if controller not in CAP_CONTROLLERS:
        raise ValueError(f"unknown cap controller {controller!r}; choose one of {CAP_CONTROLLERS}")
    closed = controller == "closed_loop"
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
        regrasp=closed,
    )
    turning_steps = int(round(settings.cycles * (hi - lo) / delta))
    options = {"radius": radius_cm / 100.0, **(scene_options or {})}
    with Simulation("shadow", "cap", options, seed=seed, physics_hz=settings.physics_hz) as sim:
        max_grasp = int((settings.approach_s + settings.max_closing_s) * settings.control_hz)
        for _ in range(max_grasp):
            x = ctl.update(touching_fingers(sim.contacts()))
            if controller == "open_loop" and ctl.state == CLOSING:
                ctl.x[ctl.r_dim] = radius_cm
                ctl.start_turning(False)
                x = ctl.x.copy()
            sim.set_targets(manifold.joint_names, ctl.posture(x))
            sim.step(per_control)
            if ctl.state == TURNING:
                break
        angles, times = [sim.scene_state()["cap_angle"]], [sim.time]
        for _ in range(turning_steps):
            x = ctl.update(touching_fingers(sim.contacts()) if closed else ())
            sim.set_targets(manifold.joint_names, ctl.posture(x))
            sim.step(per_control)
            angles.append(sim.scene_state()["cap_angle"])
            times.append(sim.time)
    turns = np.asarray(angles) / (2 * np.pi)
    ends = np.linspace(0, turning_steps, settings.cycles + 1).round().astype(int)
    per_cycle = np.degrees(np.diff(np.asarray(angles)[ends]))
    return {
        "deg_per_cycle": float(per_cycle.sum() / settings.cycles),
        "per_cycle_deg": per_cycle.tolist(),
        "found_radius": float(ctl.radius),
        "grasp_complete": bool(ctl.grasp_complete),
        "regrasps": ctl.regrasps,
        "times": np.asarray(times),
        "turns": turns - turns[0],
    }


# -- ball swapping -----------------------------------------------------------------------------
def ideal_balls(sim: Simulation, width: int = 240, height: int = 180) -> np.ndarray:
    """Ground-truth ball positions (2, 2) normalised to the marks exactly as the tracker does
    (NaN for a ball taken out of the hand)."""
    scene = sim.scene
    cam = scene.camera()
    balls_px = cam.project(scene.ball_positions(sim.client), width, height)
    marks_px = cam.project(scene.mark_positions(), width, height)
    out = normalise_points(balls_px, marks_px[0], marks_px[1])
    if scene.removed is not None:  # a ball out of the hand is not seen
        out[scene.removed] = np.nan
    return out


@dataclass
class BallSettings:
    """Ball-swap run settings (closed loop: ``k`` steps of ``delta``, ``mask``, ``tolerance``,
    ``lag``, ``max_error`` and ``refractory`` — given as ``refractory_s`` seconds of hand motion,
    one hand cycle by default, 0 = off — of :class:`ClosedLoopController`; all: ``period_s`` per latent period
    at the control rate; ``scene_options``: the balls scene's disturbance schedules, e.g.
    ``{"holds": [[10.5, 1.0]]}``; ``image_noise``: σ of seeded Gaussian pixel noise (grey levels)
    added to every camera image before the tracker; ``init_after_s``: when the feedback-initialised
    open loop takes its phase from the balls)."""

    duration_s: float = 120.0
    period_s: float = 4.0
    k: int = 5
    control_hz: float = 20.0
    camera_hz: float = 10.0
    physics_hz: float = 240.0
    camera: bool = True
    width: int = 240
    height: int = 180
    scene_options: dict = field(default_factory=dict)
    image_noise: float = 0.0
    init_after_s: float = 4.0
    seed: int = 0
    mask: str = "ball1"
    tolerance: float = 0.05
    lag: float = 0.5
    max_error: float = 0.1
    refractory_s: float = 2.0


BALL_CONTROLLERS = ("open_loop", "feedback_init", "closed_loop", "closed_loop_thesis")
"""Ball-swap controllers: fixed-phase open loop; open loop whose phase is projected once from the
balls at ``init_after_s`` (feedback-initialised); ball-gated closed loop; closed loop with the
thesis' pure projection (τ = 0)."""


def _observe(sim: Simulation, tracker: BallTracker, settings: BallSettings, rng: np.random.Generator):
    """Ball observation (2, 2) and validity: camera + tracker, or the ideal tracker."""
    if settings.camera:
        image = sim.render(settings.width, settings.height)
        if settings.image_noise > 0:
            noisy = image + rng.normal(0.0, settings.image_noise, image.shape)
            image = np.clip(noisy, 0, 255).astype(np.uint8)
        res = tracker.update(image)
        return res.balls, res.balls_valid
    balls = ideal_balls(sim, settings.width, settings.height)
    return balls, np.isfinite(balls).all(axis=1)


def ball_swap(manifold: ManipulationManifold, controller: str, settings: BallSettings) -> dict:
    """One run of ``controller`` (one of :data:`BALL_CONTROLLERS`); returns swaps_per_min, times (s)
    and swap progress (signed swaps, see :func:`handflow.plugins.simulator.metrics.swap_progress`;
    NaN while a ball is out of the hand) per control step."""
    if controller not in BALL_CONTROLLERS:
        raise ValueError(f"unknown ball controller {controller!r}; choose one of {', '.join(BALL_CONTROLLERS)}")
    t_lo, t_hi = manifold.range(manifold.time_dim)
    delta = (t_hi - t_lo) / (settings.period_s * settings.control_hz)
    per_control = int(round(settings.physics_hz / settings.control_hz))
    per_camera = max(int(round(settings.control_hz / settings.camera_hz)), 1)
    init_step = int(round(settings.init_after_s * settings.control_hz))
    tracker, rng = BallTracker(), np.random.default_rng(settings.seed)
    closed_loop = controller.startswith("closed_loop")
    tolerance = 0.0 if controller == "closed_loop_thesis" else settings.tolerance
    with Simulation("gifu", "balls", settings.scene_options, seed=settings.seed, physics_hz=settings.physics_hz) as sim:
        open_ctl = OpenLoopController(manifold, [t_lo], delta)
        closed = ClosedLoopController(
            manifold,
            settings.k,
            delta,
            settings.mask,
            tolerance,
            settings.lag,
            settings.max_error,
            refractory=settings.refractory_s / settings.period_s * (t_hi - t_lo),
        )
        plan: list = []
        last = None
        positions, times = [], []
        for step in range(int(settings.duration_s * settings.control_hz)):
            observe = closed_loop and step % per_camera == 0
            initialise = controller == "feedback_init" and step >= init_step and last is None
            if observe or (initialise and step % per_camera == 0):
                balls, valid = _observe(sim, tracker, settings, rng)
                if initialise:
                    est = closed.estimate(balls, valid)
                    if est is not None and est.error <= settings.max_error:
                        last = est.x
                        open_ctl = OpenLoopController(manifold, est.x, delta)
                else:
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
    """What ``handflow evaluate manipulation`` runs (``quick()`` is the short variant).

    Disturbances every ``disturb_every_s`` starting at ``first_disturbance_s``; with the 2 s hand
    cycle (``cycle_s``; period_s = 4 s per ball period = two hand cycles) seed 0 hits the open
    loop always at the same phase, a quarter into the rake stroke; every other seed shifts each
    disturbance by a seeded offset within one hand cycle (:func:`.disturbances.schedule_times`)
    and draws its own camera noise.  ``jobs``: worker processes for the ball runs (one task per
    seed and controller).  Cap disturbances: one a quarter cycle into the second turning cycle
    of a ``cap_disturbance_radius_cm`` cap turned ``cap_disturbance_cycles`` cycles."""

    radii_cm: tuple[float, ...] = TRAINING_RADII_CM + INTERMEDIATE_RADII_CM
    cap: CapSettings = field(default_factory=CapSettings)
    balls: BallSettings = field(default_factory=lambda: BallSettings(duration_s=48.0, image_noise=6.0))
    first_disturbance_s: float = 10.5
    disturb_every_s: float = 12.0
    cycle_s: float = 2.0
    seeds: tuple[int, ...] = (0, 1, 2)
    controllers: tuple[str, ...] = ("open_loop", "feedback_init", "closed_loop")
    classes: tuple[str, ...] = tuple(BALL_CLASSES)
    cap_classes: tuple[str, ...] = tuple(CAP_CLASSES)
    cap_disturbance_radius_cm: float = 2.5
    cap_disturbance_cycles: int = 8
    jobs: int = 1

    @classmethod
    def quick(cls) -> EvalPlan:
        return cls(
            cap=CapSettings(cycles=2),
            balls=BallSettings(duration_s=22.0, camera=False),
            seeds=(0,),
            cap_disturbance_cycles=6,
        )

    def disturbances(self, seed: int = 0) -> tuple[float, ...]:
        end = self.balls.duration_s - self.disturb_every_s / 2
        nominal = np.arange(self.first_disturbance_s, end, self.disturb_every_s)
        return schedule_times(nominal, seed, self.cycle_s)


def _controller_runs(manifold: ManipulationManifold, plan: EvalPlan, seed: int, name: str) -> dict:
    """``{"calm": run, CLASS: (times, run)}`` of one controller and seed (:func:`ball_swap` runs)."""
    times = plan.disturbances(seed)
    base = BallSettings(**{**plan.balls.__dict__, "seed": seed})
    row = {"calm": ball_swap(manifold, name, base)}
    for cls in plan.classes:
        opts = BALL_CLASSES[cls].scene_options(times)
        row[cls] = (times, ball_swap(manifold, name, BallSettings(**{**base.__dict__, "scene_options": opts})))
    return row


def _ball_runs(manifold: ManipulationManifold, plan: EvalPlan, progress) -> dict:
    """``{seed: {controller: {"calm": run, CLASS: (times, run)}}}``; ``plan.jobs`` worker processes."""
    tasks = [(seed, name) for seed in plan.seeds for name in plan.controllers]
    runs: dict = {seed: {} for seed in plan.seeds}

    def done(seed, name, row):
        runs[seed][name] = row
        direction = 1.0 if filled(row["calm"]["progress"])[-1] >= 0 else -1.0
        rates = {k: round(_rate(v if k == "calm" else v[1], "progress", direction), 1) for k, v in row.items()}
        progress(f"ball swap seed {seed} {name}: swaps/min {rates}")

    if plan.jobs <= 1:
        for seed, name in tasks:
            done(seed, name, _controller_runs(manifold, plan, seed, name))
    else:
        with ProcessPoolExecutor(plan.jobs) as pool:
            futures = {pool.submit(_controller_runs, manifold, plan, seed, name): (seed, name) for seed, name in tasks}
            for future in as_completed(futures):
                done(*futures[future], future.result())
    return {seed: {name: runs[seed][name] for name in plan.controllers} for seed in plan.seeds}


def _class_summary(runs: dict, classes: dict, key: str, cycle_s: float) -> dict:
    """``{CLASS: {controller: {rate, rate_spread, calm_rate, recovered_share, failures,
    recovery_s, disturbances}}}`` pooled over seeds (rates: median over seeds; recovery: rate
    over one hand cycle ``cycle_s`` back to half the calm rate, :func:`.disturbances.recovery_times`)."""
    out: dict = {}
    seeds = list(runs)
    for cls in classes:
        out[cls] = {}
        for name in runs[seeds[0]]:
            rates, calms, rec = [], [], []
            for seed in seeds:
                calm = runs[seed][name]["calm"]
                times, run = runs[seed][name][cls]
                direction = 1.0 if filled(calm[key])[-1] >= 0 else -1.0
                calm_rate = _rate(calm, key, direction)
                rates.append(_rate(run, key, direction))
                calms.append(calm_rate)
                ends = np.asarray(times) + classes[cls].duration_s
                rec.extend(
                    recovery_times(
                        run["times"],
                        run[key],
                        times,
                        ends,
                        calm_rate / UNIT[key],
                        window_s=cycle_s,
                        direction=direction,
                    )
                )
            out[cls][name] = {
                "rate": float(np.median(rates)),
                "rate_spread": [float(min(rates)), float(max(rates))],
                "calm_rate": float(np.median(calms)),
                **summarise(rec, cycle_s),
                "disturbances": len(rec),
            }
    return out


UNIT = {"progress": 1.0, "turns": 360.0}
"""Reported rate units per progress unit: swaps per swap, degrees per cap turn."""


def _rate(run: dict, key: str, direction: float = 1.0) -> float:
    """Progress per minute of a run in ``direction`` (balls: net whole swaps per minute, as
    :func:`~handflow.plugins.simulator.metrics.swaps_per_minute`; cap: degrees per minute)."""
    t, prog = run["times"], direction * filled(run[key])
    minutes = float(t[-1] - t[0]) / 60.0
    if key == "progress":
        return max(float(np.floor(prog[-1] + 1e-9)), 0.0) / minutes
    return UNIT[key] * float(prog[-1] - prog[0]) / minutes


def hardest_class(classes: dict) -> str:
    """The class in which the open loop's rate is lowest (without an open loop: the first controller's)."""
    return min(classes, key=lambda c: classes[c].get("open_loop", next(iter(classes[c].values())))["rate"])


def ball_swap_report(manifold: ManipulationManifold, plan: EvalPlan, progress=lambda line: None) -> tuple:
    """Per controller the calm rate and the rate under the hardest class (``ball_swap`` rows),
    the per-class summary (:func:`_class_summary`) and the runs (for plots)."""
    runs = _ball_runs(manifold, plan, progress)
    classes = _class_summary(runs, {c: BALL_CLASSES[c] for c in plan.classes}, "progress", plan.cycle_s)
    hardest = hardest_class(classes)
    rows = {
        name: {
            "swaps_per_min": classes[hardest][name]["calm_rate"],
            "swaps_per_min_disturbed": classes[hardest][name]["rate"],
            "hardest_class": hardest,
            "recovered_share": classes[hardest][name]["recovered_share"],
            "disturbances": classes[hardest][name]["disturbances"],
        }
        for name in plan.controllers
    }
    return rows, classes, runs


def cap_disturbance_report(manifold: ManipulationManifold, plan: EvalPlan, progress=lambda line: None) -> tuple:
    """Cap classes on the constructed manifold, for each of :data:`CAP_CONTROLLERS` (open loop at
    the known radius, grasp by navigation once, and with regrasps); rate = cap rotation in degrees
    per minute; one disturbance per run; recovery as for the balls, over one turning cycle."""
    settings = CapSettings(**{**plan.cap.__dict__, "cycles": plan.cap_disturbance_cycles})
    radius = plan.cap_disturbance_radius_cm
    runs: dict = {}
    for seed in plan.seeds:
        for name in CAP_CONTROLLERS:
            calm = cap_turning(manifold, radius, settings, seed=seed, controller=name)
            row = runs.setdefault(seed, {})[name] = {"calm": calm}
            start = calm["times"][0]
            times = schedule_times([start + settings.cycle_s * 1.25], seed, settings.cycle_s)
            for cls in plan.cap_classes:
                opts = CAP_CLASSES[cls].scene_options(times)
                row[cls] = (times, cap_turning(manifold, radius, settings, seed, opts, name))
            direction = 1.0 if calm["turns"][-1] >= 0 else -1.0
            rates = {k: round(_rate(v if k == "calm" else v[1], "turns", direction), 1) for k, v in row.items()}
            progress(f"cap seed {seed} {name}: deg/min {rates}")
    cap_classes = {c: CAP_CLASSES[c] for c in plan.cap_classes}
    classes = _class_summary(runs, cap_classes, "turns", settings.cycle_s)
    return classes, runs


def disturbance_classes(classes: dict) -> dict:
    """``{class: {controller: {"rate", "recovered_share"}}}`` (the JSON's short form)."""
    return {
        cls: {name: {"rate": v["rate"], "recovered_share": v["recovered_share"]} for name, v in row.items()}
        for cls, row in classes.items()
    }


def evaluate(
    constructed: ManipulationManifold,
    learned: ManipulationManifold,
    balls: ManipulationManifold,
    plan: EvalPlan,
    ball_path,
    progress=lambda line: None,
    plots=None,
) -> dict:
    """The JSON of ``handflow evaluate manipulation``; ``plots``: folder for the rate-over-time
    figures (:mod:`.plots`), ``None`` = none."""
    cap = {}
    for key, manifold in (("cap_turning", constructed), ("cap_turning_learned", learned)):
        cap[key] = {}
        for r in sorted(plan.radii_cm):
            res = cap_turning(manifold, r, plan.cap)
            cap[key][f"{r:g}"] = {k: v for k, v in res.items() if k not in ("times", "turns")}
            progress(f"{key} r={r:g} cm: {res['deg_per_cycle']:.1f} deg/cycle, found radius {res['found_radius']:.2f}")
    report = learned.model.provenance_
    rows, classes, runs = ball_swap_report(balls, plan, progress)
    cap_classes, cap_runs = cap_disturbance_report(constructed, plan, progress)
    if plots is not None:
        from .plots import plot_rates

        plot_rates(runs, {c: BALL_CLASSES[c] for c in plan.classes}, "progress", plots, "balls", plan.cycle_s)
        plot_rates(cap_runs, {c: CAP_CLASSES[c] for c in plan.cap_classes}, "turns", plots, "cap", plan.cycle_s)
    return {
        **cap,
        "ball_swap": rows,
        "disturbance_classes": disturbance_classes({**classes, **cap_classes}),
        "disturbance_details": {**classes, **cap_classes},
        "seeds": list(plan.seeds),
        "radius_spearman": report.get("spearman"),
        "radius_separation": report.get("separation"),
        "loop_latency_ms": loop_latency_ms(ball_path, k=plan.balls.k),
    }
