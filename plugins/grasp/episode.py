"""One grasp trial in pybullet: build the scene, run the controller, test stability (docs/grasping.md).

The simulator (:class:`handflow.plugins.simulator.simulation.Simulation`, scene ``grasp``) puts the object on
a table under the palm-down hand.  Documented choices (:class:`EpisodeConfig`):

- ``floating=True`` (default): as in the thesis (4.3: zero gravity, object hovering in front of the
  fixed palm, free to move) the table is removed and gravity switched off while grasping, so the
  fingers can close around the object; ``floating=False`` grasps on the table under gravity;
- ``object_damping`` (default 0.99): while grasping, the object moves as in a viscous medium
  (pybullet ``linearDamping``/``angularDamping``; Bullet's multibody damping decelerates by
  ``d·v·(1 + |v|)``: at 0.99 a 0.5 m/s push keeps half its speed after 0.5 s, a time constant of
  about 1/d at low speed) — the grasp is quasi-static: fingers still push the object into the palm,
  but a touch no longer sends it flying, so the outcome depends on the hand's
  posture rather than on the bounce (the undamped grasp flipped 19 of 150 outcomes for a 2 %
  change of the closing speed, the damped one 13, 4 of them box/cylinder instead of 10).  The stability
  test runs with pybullet's default damping (0.04);
- ``lateral_friction`` (default 0.8, the scene's): the object's friction coefficient (pybullet
  multiplies it with the hand's); the evaluation grid's harder conditions lower it.

The controller runs at ``rate_hz`` on the measured posture and the segments touching the object
(contacts with ``ignore_bodies``, the table by default, are not object contacts).  The grasp phase
ends when the controller is finished for ``settle_s`` or after ``grasp_s``; then the wrench-space
quality is computed and the :class:`DisturbanceTest` runs with gravity on.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from handflow.plugins.simulator.scenes import GRASP_OBJECTS, GraspScene
from handflow.plugins.simulator.simulation import Simulation

from ..simulator.bullet import pybullet as p
from .controller import ExperienceGraspController
from .stability import DisturbanceTest, grasp_wrench_quality, object_contacts, random_directions, rotation_angle_deg


@dataclass(frozen=True)
class GraspPose:
    """Object placement relative to the scene's default (m, m, m, deg): see :data:`.experience.POSE_FIELDS`."""

    x: float = 0.0
    y: float = 0.0
    gap: float = 0.03
    yaw_deg: float = 0.0

    def as_array(self) -> np.ndarray:
        return np.array([self.x, self.y, self.gap, self.yaw_deg])


DEFAULT_DAMPING = 0.04
"""pybullet's default linear and angular damping of a body (the stability test runs with it)."""

CENTRED_POSE = GraspPose(x=0.035, y=0.0, gap=0.005, yaw_deg=-30.0)
"""Reference pose of the tests: the lying cylinder under the knuckles, turned 30° towards the thumb."""


@dataclass(frozen=True)
class EpisodeConfig:
    """Timing of one trial and which bodies are not grasp contacts."""

    physics_hz: float = 240.0
    grasp_s: float = 3.0
    settle_s: float = 0.25
    floating: bool = True
    object_damping: float = 0.99
    ignore_bodies: tuple[str, ...] = ("table",)
    lateral_friction: float = 0.8
    test: DisturbanceTest = field(default_factory=DisturbanceTest)

    def __post_init__(self) -> None:
        if not 0.0 <= self.object_damping < 1.0:
            raise ValueError(f"object_damping must be in [0, 1), got {self.object_damping}")
        if not self.lateral_friction > 0.0:
            raise ValueError(f"lateral_friction must be > 0, got {self.lateral_friction}")


@dataclass
class GraspResult:
    """Outcome of one trial."""

    object: str
    pose: np.ndarray
    stable: bool
    valid: bool
    posture: np.ndarray
    touched: list[str]
    quality: float
    shift_m: float
    turn_deg: float
    grasp_time_s: float
    n_matches: int

    def summary(self) -> dict:
        d = asdict(self)
        d["pose"], d["posture"] = self.pose.tolist(), self.posture.tolist()
        return d


def object_radius(obj: str) -> float:
    """Torque scale of an object for the wrench quality: its largest half-extent in the grasp region."""
    dims = GRASP_OBJECTS[obj][1]
    if "radius" in dims:
        return float(dims["radius"])
    return float(np.linalg.norm(dims["halfExtents"][:2]))


def touched_segments(sim: Simulation, ignore) -> list[str]:
    c = sim.contacts()
    return sorted({s for s, b in zip(c.segments, c.bodies) if b not in ignore})


def run_grasp(
    obj: str,
    pose: GraspPose,
    controller: ExperienceGraspController,
    config: EpisodeConfig = EpisodeConfig(),
    seed: int = 0,
    hand: str = "shadow",
) -> GraspResult:
    """Grasp ``obj`` at ``pose`` with ``controller`` and test the grasp's stability."""
    scene = GraspScene(
        object=obj,
        position=(pose.x, pose.y),
        yaw_deg=pose.yaw_deg,
        gap_below_palm=pose.gap,
        lateral_friction=config.lateral_friction,
        start_posture=dict(controller.config.pregrasp),
    )
    with Simulation(hand=hand, scene=scene, seed=seed, physics_hz=config.physics_hz) as sim:
        if config.floating:
            remove_table(sim, scene)
            p.setGravity(0, 0, 0, physicsClientId=sim.client)
        set_damping(sim, scene, config.object_damping)
        controller.reset()
        p.performCollisionDetection(physicsClientId=sim.client)
        if touched_segments(sim, config.ignore_bodies):  # thesis 4.3: initially colliding placements are ignored
            q = sim.joint_positions()
            return GraspResult(obj, pose.as_array(), False, False, q, [], 0.0, 0.0, 0.0, 0.0, 0)
        per_cycle = max(1, int(round(config.physics_hz / controller.config.rate_hz)))
        cycles = int(config.grasp_s * controller.config.rate_hz)
        settle = max(1, int(config.settle_s * controller.config.rate_hz))
        done_for = 0
        for _k in range(cycles):
            q = sim.joint_positions()
            touched = touched_segments(sim, config.ignore_bodies)
            targets = controller.step(q, touched)
            sim.set_targets(controller.names, targets)
            sim.step(per_cycle)
            done_for = done_for + 1 if controller.finished(sim.joint_positions()) else 0
            if done_for >= settle:
                break
        if controller.phase != "grip":
            sim.set_targets(controller.names, controller.grip(sim.joint_positions()))
            sim.step(int(config.settle_s * config.physics_hz))
        set_damping(sim, scene, DEFAULT_DAMPING)
        grasp_time = sim.time
        posture = sim.joint_positions()
        touched = touched_segments(sim, config.ignore_bodies)
        obj_id = scene.object_id
        pts, nrm = object_contacts(sim.client, sim.hand_id, obj_id)
        pos0, orn0 = p.getBasePositionAndOrientation(obj_id, physicsClientId=sim.client)
        quality = grasp_wrench_quality(pts, nrm, pos0, object_radius(obj))
        shift, turn, n_touch = disturb(sim, scene, config.test, np.random.default_rng(seed))
        stable = (
            shift < config.test.max_shift_m and turn < config.test.max_turn_deg and n_touch >= config.test.min_contacts
        )
        return GraspResult(
            obj,
            pose.as_array(),
            bool(stable),
            True,
            posture,
            touched,
            quality,
            shift,
            turn,
            grasp_time,
            controller.n_matches,
        )


def set_damping(sim: Simulation, scene: GraspScene, damping: float) -> None:
    p.changeDynamics(scene.object_id, -1, linearDamping=damping, angularDamping=damping, physicsClientId=sim.client)


def remove_table(sim: Simulation, scene: GraspScene) -> None:
    for key, name in list(scene.bodies.items()):
        if name == "table":
            p.removeBody(key[0], physicsClientId=sim.client)
            del scene.bodies[key]


def disturb(
    sim: Simulation, scene: GraspScene, test: DisturbanceTest, rng: np.random.Generator
) -> tuple[float, float, int]:
    """Gravity on, table gone, hold, push the object randomly → (shift m, turn deg, touching segments)."""
    client, obj_id = sim.client, scene.object_id
    remove_table(sim, scene)
    p.setGravity(0, 0, -9.81, physicsClientId=client)
    pos0, orn0 = p.getBasePositionAndOrientation(obj_id, physicsClientId=client)
    hz = sim.physics_hz
    sim.step(int(test.hold_s * hz))
    forces = random_directions(rng, test.n_pushes) * test.force_n
    torques = random_directions(rng, test.n_pushes) * test.torque_nm
    for f, t in zip(forces, torques):
        for _ in range(int(test.push_s * hz)):
            pos, _ = p.getBasePositionAndOrientation(obj_id, physicsClientId=client)
            p.applyExternalForce(obj_id, -1, f.tolist(), pos, p.WORLD_FRAME, physicsClientId=client)
            p.applyExternalTorque(obj_id, -1, t.tolist(), p.WORLD_FRAME, physicsClientId=client)
            sim.step(1)
        sim.step(int(test.rest_s * hz))
    pos1, orn1 = p.getBasePositionAndOrientation(obj_id, physicsClientId=client)
    shift = float(np.linalg.norm(np.subtract(pos1, pos0)))
    n_touch = len({c[3] for c in p.getContactPoints(bodyA=sim.hand_id, bodyB=obj_id, physicsClientId=client)})
    return shift, rotation_angle_deg(orn0, orn1), n_touch
