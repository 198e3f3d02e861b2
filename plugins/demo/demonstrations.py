"""Record demonstrations to MCAP: the thesis pipeline with a scripted operator (docs/manipulation.md).

Recordings use :class:`handflow.framework.files.mcap_writer.McapWriter` (JSON-schema channels, ``encode``d payloads,
``log_time`` = simulated time in ns from the start of the recording), so ``handflow.framework.files.mcap_reader.
read_messages`` reads them back.  Everything is seeded: the same arguments give the same file.

Cap turning (``record_cap``) — topics (graph name ``demo_cap``):

- ``handflow/demo_cap/sim/joints`` — JointState (hand ``shadow``, 24 joints): the recorded
  posture, i.e. the *collision-corrected* joint angles after physics;
- ``handflow/demo_cap/demo/label`` — Array with names ``[radius, sequence, posture]`` at the same
  log time as each posture: cap radius (m), global sequence id, posture index in the sequence;
- ``handflow/demo_cap/demo/targets`` — JointState: the demonstrator's commanded targets (only
  with ``include_targets=True``; off by default to keep recordings small);
- ``handflow/demo_cap/sim/scene`` — Array ``[cap_angle, cap_velocity, cap_radius]``;
- metadata ``handflow.demo``: task, hand, seed, radii, sequences per radius, rates.

Ball swapping (``record_balls``) — topics (graph ``demo_balls``): ``sim/joints`` (JointState,
``gifu``, 20 joints), ``tracker/balls`` and ``tracker/marks`` (Points2D from the colour-blob
tracker on rendered images), ``sim/scene`` (ground-truth ball positions), ``demo/label`` (Array
``[swap_cycle, hand_cycle, hand_phase]`` per frame; a swap cycle = one ball period = two hand
cycles) and ``demo/observation`` — Array of d = 20 (the 16 independent Gifu joints, then p1 and
p2, the two tracked balls in track-id order); written only when both balls and both marks were
seen (a frame with a lost blob has no observation — nothing is invented).

Read them back with :mod:`handflow.plugins.demo.loaders`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from handflow.framework.files.mcap_writer import McapWriter
from handflow.framework.messages import Array, JointState, Points2D
from handflow.plugins.hands.joints import GIFU, SHADOW
from handflow.plugins.simulator.metrics import count_swaps
from handflow.plugins.simulator.simulation import Simulation
from handflow.plugins.tracker.blobs import BallTracker

from .ball_swap import BallSwapMotion
from .cap_turning import CapTurningDemonstrator

CAP_RADII = (0.015, 0.020, 0.025, 0.030, 0.035)
"""Cap radii of the thesis (m)."""
CAP_PREFIX = "handflow/demo_cap"
BALLS_PREFIX = "handflow/demo_balls"
GIFU_DOF = [n for n in GIFU.names if n not in GIFU.coupled]
"""The 16 independent Gifu joints (coupled DIPs dropped) in the observation vector."""
OBSERVATION_NAMES = GIFU_DOF + ["p1_x", "p1_y", "p2_x", "p2_y"]
BALL_LABEL_NAMES = ["swap_cycle", "hand_cycle", "hand_phase"]
"""Label Array of every ball frame: swap cycle (ball period), hand cycle, hand phase in (0, 1]."""

Progress = Callable[[str], None]


@dataclass(frozen=True)
class CapRecordingSummary:
    path: Path
    postures: int
    sequences: dict[float, int]


def _ns(steps: int, hz: float) -> int:
    return int(round(steps * 1e9 / hz))


def record_cap(
    path: str | Path,
    radii=CAP_RADII,
    sequences: int | None = None,
    seed: int = 0,
    demonstrator: CapTurningDemonstrator | None = None,
    record_every: int = 10,
    postures_range: tuple[int, int] = (30, 45),
    physics_hz: float = 240.0,
    include_targets: bool = False,
    progress: Progress | None = None,
) -> CapRecordingSummary:
    """Cap-turning demonstrations: per radius ``sequences`` cycles (None: 5–9 drawn from the seed).

    Each sequence is one turning cycle of 30–45 postures sampled every ``record_every`` physics
    steps; the hand runs the cycles back to back against a fresh cap per radius.
    """
    radii = [float(r) for r in radii]
    bad = [r for r in radii if not 0.01 <= r <= 0.05]
    if bad:
        raise ValueError(f"cap radii must be given in metres within 0.01–0.05 (e.g. 0.025), got {bad}")
    if sequences is not None and sequences < 1:
        raise ValueError(f"sequences must be at least 1, got {sequences}")
    demo = demonstrator or CapTurningDemonstrator()
    rng = np.random.default_rng(seed)
    counts = {r: int(sequences if sequences is not None else rng.integers(5, 10)) for r in radii}
    steps_total, seq_id, postures = 0, 0, 0
    with McapWriter(path, flush_interval_s=None) as w:
        w.add_metadata(
            "handflow.demo",
            {
                "task": "cap_turning",
                "hand": "shadow",
                "seed": seed,
                "radii_m": ",".join(map(str, radii)),
                "sequences": ",".join(str(counts[r]) for r in radii),
                "physics_hz": physics_hz,
                "record_every_steps": record_every,
                "posture_topic": f"{CAP_PREFIX}/sim/joints",
                "label_topic": f"{CAP_PREFIX}/demo/label",
            },
        )
        for r in radii:
            with Simulation("shadow", "cap", {"radius": r}, seed=seed, physics_hz=physics_hz) as sim:
                first = demo.targets(np.zeros(1), r, demo.variation(rng))[0]
                sim.set_targets(SHADOW.names, first)
                sim.step(int(0.25 * physics_hz))
                for k in range(counts[r]):
                    var = demo.variation(rng)
                    n_post = int(rng.integers(postures_range[0], postures_range[1] + 1))
                    n_steps = n_post * record_every
                    targets = demo.targets(np.arange(n_steps) / n_steps, r, var)
                    for i in range(n_steps):
                        sim.set_targets(SHADOW.names, targets[i])
                        sim.step(1)
                        if (i + 1) % record_every == 0:
                            t = _ns(steps_total + sim.steps, physics_hz)
                            js = sim.joint_state()
                            w.write(
                                f"{CAP_PREFIX}/sim/joints",
                                JointState(names=js.names, positions=js.positions, hand="shadow"),
                                t,
                                t,
                            )
                            w.write(
                                f"{CAP_PREFIX}/demo/label",
                                Array(data=[r, seq_id, i // record_every], names=["radius", "sequence", "posture"]),
                                t,
                                t,
                            )
                            if include_targets:
                                w.write(
                                    f"{CAP_PREFIX}/demo/targets",
                                    JointState(names=list(SHADOW.names), positions=sim.targets, hand="shadow"),
                                    t,
                                    t,
                                )
                            state = sim.scene_state()
                            w.write(
                                f"{CAP_PREFIX}/sim/scene", Array(data=list(state.values()), names=list(state)), t, t
                            )
                            postures += 1
                    seq_id += 1
                    if progress:
                        progress(f"cap r={r * 100:.1f} cm: sequence {k + 1}/{counts[r]} ({postures} postures)")
                steps_total += sim.steps
    return CapRecordingSummary(Path(path), postures, counts)


@dataclass(frozen=True)
class BallsRecordingSummary:
    path: Path
    frames: int
    observations: int
    swaps: int


def record_balls(
    path: str | Path,
    cycles: int = 4,
    seed: int = 0,
    motion: BallSwapMotion | None = None,
    rate_hz: float = 25.0,
    width: int = 240,
    height: int = 180,
    physics_hz: float = 240.0,
    scene_options: dict | None = None,
    progress: Progress | None = None,
) -> BallsRecordingSummary:
    """Ball-swapping demonstrations: ``cycles`` swap cycles (ball periods = 2 hand cycles each), camera + tracker at ``rate_hz``.

    Returns the number of frames, of d = 20 observations and of swaps done (ground truth,
    :func:`handflow.plugins.simulator.metrics.count_swaps`).
    """
    if cycles < 1:
        raise ValueError(f"cycles must be at least 1, got {cycles}")
    if not 1.0 <= rate_hz <= physics_hz:
        raise ValueError(f"rate_hz must lie in 1–{physics_hz:g} Hz, got {rate_hz}")
    motion = motion or BallSwapMotion()
    every = max(int(round(physics_hz / rate_hz)), 1)
    n_steps = int(round(motion.period_s * physics_hz))
    tracker = BallTracker()
    dof = [GIFU.index(n) for n in GIFU_DOF]
    frames = observations = 0
    truth = []
    with (
        McapWriter(path, flush_interval_s=None) as w,
        Simulation("gifu", "balls", scene_options, seed=seed, physics_hz=physics_hz) as sim,
    ):
        w.add_metadata(
            "handflow.demo",
            {
                "task": "ball_swapping",
                "hand": "gifu",
                "seed": seed,
                "cycles": cycles,
                "rate_hz": rate_hz,
                "hand_period_s": motion.period_s,
                "hand_cycles_per_swap_cycle": 2,
                "image_size": f"{width}x{height}",
                "observation_topic": f"{BALLS_PREFIX}/demo/observation",
                "label_topic": f"{BALLS_PREFIX}/demo/label",
                "observation_names": ",".join(OBSERVATION_NAMES),
            },
        )
        sim.set_targets(GIFU.names, motion.targets(0.0)[0])
        sim.step(int(0.5 * physics_hz))
        start = sim.steps
        for hand_cycle in range(2 * cycles):
            for i in range(n_steps):
                sim.set_targets(GIFU.names, motion.targets(i / n_steps)[0])
                sim.step(1)
                if (i + 1) % every:
                    continue
                t = _ns(sim.steps - start, physics_hz)
                js = sim.joint_state()
                res = tracker.update(sim.render(width, height))
                truth.append(sim.scene.palm_plane_positions(sim.client))
                w.write(
                    f"{BALLS_PREFIX}/sim/joints", JointState(names=js.names, positions=js.positions, hand="gifu"), t, t
                )
                w.write(
                    f"{BALLS_PREFIX}/tracker/balls",
                    Points2D(points=res.balls, valid=res.balls_valid, ids=res.ids),
                    t,
                    t,
                )
                w.write(
                    f"{BALLS_PREFIX}/tracker/marks",
                    Points2D(points=res.marks_px, valid=res.marks_valid, ids=[0, 1]),
                    t,
                    t,
                )
                state = sim.scene_state()
                w.write(f"{BALLS_PREFIX}/sim/scene", Array(data=list(state.values()), names=list(state)), t, t)
                w.write(
                    f"{BALLS_PREFIX}/demo/label",
                    Array(data=[hand_cycle // 2, hand_cycle, (i + 1) / n_steps], names=BALL_LABEL_NAMES),
                    t,
                    t,
                )
                frames += 1
                if res.balls_valid.all():
                    obs = np.concatenate([js.positions[dof], res.balls.reshape(-1)])
                    w.write(f"{BALLS_PREFIX}/demo/observation", Array(data=obs, names=OBSERVATION_NAMES), t, t)
                    observations += 1
            if progress:
                progress(f"balls: hand cycle {hand_cycle + 1}/{2 * cycles} ({observations} observations)")
    truth_arr = np.array(truth)
    return BallsRecordingSummary(Path(path), frames, observations, count_swaps(truth_arr[:, 0], truth_arr[:, 1]))
