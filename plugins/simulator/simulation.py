"""The plain pybullet simulation of a hand in a scene, usable without the runtime (docs/simulator.md).

::

    with Simulation(hand="shadow", scene="cap", scene_options={"radius": 0.02}, seed=0) as sim:
        sim.set_targets(["FFJ3", "MFJ3"], [1.0, 1.0])
        sim.step(240)                      # one simulated second at the fixed 240 Hz
        sim.joint_state(), sim.contacts(), sim.scene_state(), sim.render(320, 240)

Headless (``pybullet.DIRECT``), fixed physics rate, position control of every joint with the
hand's torque limits (``max_torque`` of the skeleton) and :class:`MotorGains`; joint couplings are
enforced on the commanded targets (:mod:`handflow.plugins.simulator.couplings`).  The joint state read back
after stepping is the *collision-corrected* posture: fingers stop at the objects they touch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from handflow.framework.messages import Contacts, JointState
from handflow.plugins.hands.joints import HAND_MODELS

from .bullet import pybullet as p
from .couplings import DEFAULT_COUPLING, CouplingRule
from .hand_geometry import build_skeleton
from .scenes import Scene, make_scene
from .urdf import write_urdf


@dataclass(frozen=True)
class MotorGains:
    """pybullet position-motor settings (documented choice; realistic for a tendon/servo hand).

    ``position_gain``/``velocity_gain`` are pybullet's constraint-motor gains; ``max_velocity``
    (rad/s) limits joint speed like real hand actuators (~2–3 rad/s); the torque limit per joint is
    the skeleton's ``max_torque`` times ``torque_scale``.
    """

    position_gain: float = 0.1
    velocity_gain: float = 1.0
    max_velocity: float = 2.5
    torque_scale: float = 1.0


class Simulation:
    """A hand model (``human`` | ``shadow`` | ``gifu``) in a scene (``empty`` | ``cap`` | ``balls`` | ``grasp``)."""

    def __init__(
        self,
        hand: str = "shadow",
        scene: str | Scene = "empty",
        scene_options: dict | None = None,
        seed: int | None = 0,
        physics_hz: float = 240.0,
        gains: MotorGains = MotorGains(),
        coupling: CouplingRule | None = None,
        urdf_dir: str | None = None,
    ) -> None:
        if hand not in HAND_MODELS:
            raise ValueError(f"unknown hand '{hand}'; choose one of {', '.join(HAND_MODELS)}")
        if not 30.0 <= physics_hz <= 2000.0:
            raise ValueError(f"physics_hz must lie in 30–2000 Hz, got {physics_hz}")
        self.model = HAND_MODELS[hand]
        self.skeleton = build_skeleton(hand)
        self.scene = scene if isinstance(scene, Scene) else make_scene(scene, scene_options)
        self.scene.palm_thickness = self.skeleton.palm_size[1]
        self.physics_hz = float(physics_hz)
        self.gains = gains
        self.steps = 0
        self.rng = np.random.default_rng(seed)
        self.client = p.connect(p.DIRECT)
        try:
            p.setGravity(0, 0, -9.81, physicsClientId=self.client)
            p.setTimeStep(1.0 / self.physics_hz, physicsClientId=self.client)
            pos, orn = self.scene.hand_pose()
            self.hand_id = p.loadURDF(
                str(write_urdf(hand, urdf_dir)),
                pos,
                orn,
                useFixedBase=True,
                flags=p.URDF_MAINTAIN_LINK_ORDER,
                physicsClientId=self.client,
            )
            self._init_joints(coupling)
            self.scene.build(self.client, self.rng)
        except Exception:
            p.disconnect(self.client)
            raise

    # -- setup ---------------------------------------------------------------------------------
    def _init_joints(self, coupling: CouplingRule | None) -> None:
        info = [
            p.getJointInfo(self.hand_id, i, physicsClientId=self.client)
            for i in range(p.getNumJoints(self.hand_id, physicsClientId=self.client))
        ]
        by_name = {i[1].decode(): i[0] for i in info}
        self.link_names = {i[0]: i[12].decode() for i in info}
        self.link_names[-1] = self.skeleton.base
        self.names = self.model.names
        self.index = {n: k for k, n in enumerate(self.names)}
        self.joint_ids = np.array([by_name[n] for n in self.names])
        self.lower, self.upper = self.model.lower, self.model.upper
        torque = {j.name: j.max_torque for j in self.skeleton.joints}
        self.max_torque = np.array([torque[n] for n in self.names]) * self.gains.torque_scale
        self.coupled = np.array([self.index[c] for c in self.model.coupled], dtype=int)
        self.drivers = np.array([self.index[d] for d in self.model.coupled.values()], dtype=int)
        self.coupling = coupling or DEFAULT_COUPLING.get(self.model.name)
        for jid in self.joint_ids:  # the motor array call has no velocity limit; it is a joint property
            p.changeDynamics(
                self.hand_id, int(jid), maxJointVelocity=self.gains.max_velocity, physicsClientId=self.client
            )
        self.commanded = self.model.clip(np.zeros(len(self.names)))
        start = self.scene.initial_posture()
        self.set_targets(list(start), list(start.values()))
        for jid, q in zip(self.joint_ids, self.targets):
            p.resetJointState(self.hand_id, int(jid), float(q), physicsClientId=self.client)

    # -- control -------------------------------------------------------------------------------
    def set_targets(self, names, positions) -> None:
        """Command joint targets by name (rad); joints not named keep their last target.

        Unknown names raise ``ValueError`` listing the hand's joints; targets are clipped to the
        joint limits; couplings are applied to the commanded targets.
        """
        names = list(names)
        q = np.asarray(positions, dtype=float).reshape(-1)
        if len(names) != q.size:
            raise ValueError(f"{len(names)} joint names for {q.size} target positions")
        unknown = [n for n in names if n not in self.index]
        if unknown:
            raise ValueError(
                f"hand '{self.model.name}' has no joint(s) {unknown}; its joints are: {', '.join(self.names)}"
            )
        if not np.isfinite(q).all():
            raise ValueError(
                f"joint targets must be finite, got NaN/inf for {[n for n, v in zip(names, q) if not np.isfinite(v)]}"
            )
        self.commanded[[self.index[n] for n in names]] = q
        self.targets = self.model.clip(self.commanded)
        if self.coupled.size and self.coupling is not None:
            self.targets[self.coupled] = self.coupling(self.targets[self.coupled], self.targets[self.drivers])
            self.targets = self.model.clip(self.targets)
        p.setJointMotorControlArray(
            self.hand_id,
            self.joint_ids.tolist(),
            p.POSITION_CONTROL,
            targetPositions=self.targets.tolist(),
            forces=self.max_torque.tolist(),
            positionGains=[self.gains.position_gain] * len(self.names),
            velocityGains=[self.gains.velocity_gain] * len(self.names),
            physicsClientId=self.client,
        )

    def step(self, n: int = 1) -> None:
        """Advance the physics by ``n`` fixed steps of ``1 / physics_hz`` seconds.

        Before each step the scene's :meth:`~handflow.plugins.simulator.scenes.Scene.before_step` hook runs
        at the current simulated time (e.g. the ball scene's scheduled pushes).
        """
        for _ in range(int(n)):
            self.scene.before_step(self.client, self.time)
            p.stepSimulation(physicsClientId=self.client)
            self.steps += 1

    @property
    def time(self) -> float:
        """Simulated time in seconds."""
        return self.steps / self.physics_hz

    # -- observation ---------------------------------------------------------------------------
    def joint_positions(self) -> np.ndarray:
        """Measured joint angles in the hand model's order."""
        states = p.getJointStates(self.hand_id, self.joint_ids.tolist(), physicsClientId=self.client)
        return np.array([s[0] for s in states])

    def joint_state(self) -> JointState:
        """Collision-corrected posture after physics (positions and velocities, model order)."""
        states = p.getJointStates(self.hand_id, self.joint_ids.tolist(), physicsClientId=self.client)
        return JointState(
            names=list(self.names),
            positions=np.array([s[0] for s in states]),
            velocities=np.array([s[1] for s in states]),
            hand=self.model.name,
        )

    def contacts(self) -> Contacts:
        """Per touching (hand segment, scene body) pair the summed normal force in N."""
        total: dict[tuple[str, str], float] = {}
        for c in p.getContactPoints(bodyA=self.hand_id, physicsClientId=self.client):
            if c[2] == self.hand_id:
                continue
            key = (self.link_names[c[3]], self.scene.body_name(c[2], c[4]))
            total[key] = total.get(key, 0.0) + float(c[9])
        keys = sorted(total)
        return Contacts(
            segments=[k[0] for k in keys], bodies=[k[1] for k in keys], forces=np.array([total[k] for k in keys])
        )

    def scene_state(self) -> dict[str, float]:
        """The scene's observable state (e.g. ``cap_angle``, ball positions)."""
        return self.scene.state(self.client)

    def render(self, width: int = 320, height: int = 240) -> np.ndarray:
        """RGB image (height, width, 3) from the scene's camera (TinyRenderer)."""
        return self.scene.camera().render(self.client, width, height)

    def link_position(self, link: str) -> np.ndarray:
        """World position of a hand link's frame origin (e.g. ``"FF_distal"``)."""
        ids = {v: k for k, v in self.link_names.items()}
        if link not in ids:
            raise ValueError(f"hand '{self.model.name}' has no link '{link}'; links: {', '.join(sorted(ids))}")
        if ids[link] == -1:  # pybullet's base position is its centre of mass, not the link frame
            return self.link_poses()[link][0]
        return np.array(
            p.getLinkState(self.hand_id, ids[link], computeForwardKinematics=True, physicsClientId=self.client)[4]
        )

    def link_poses(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """World pose (position, quaternion x, y, z, w) of every hand link's URDF frame as pybullet has it now."""
        com_pos, com_orn = p.getBasePositionAndOrientation(self.hand_id, physicsClientId=self.client)
        local_pos, local_orn = p.getDynamicsInfo(self.hand_id, -1, physicsClientId=self.client)[3:5]
        base_rot = Rotation.from_quat(com_orn) * Rotation.from_quat(local_orn).inv()  # base COM → link frame
        poses = {self.skeleton.base: (np.array(com_pos) - base_rot.apply(local_pos), base_rot.as_quat())}
        ids = [int(i) for i in sorted(self.link_names) if i >= 0]
        states = p.getLinkStates(self.hand_id, ids, computeForwardKinematics=True, physicsClientId=self.client)
        for i, state in zip(ids, states):
            poses[self.link_names[i]] = (np.array(state[4]), np.array(state[5]))
        return poses

    # -- lifetime ------------------------------------------------------------------------------
    def close(self) -> None:
        if self.client is not None and p.isConnected(self.client):
            p.disconnect(self.client)
        self.client = None

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
