"""Manipulation scenes: bottle cap, Chinese health balls, grasp objects, empty (docs/simulator.md).

A scene places the hand's base link (``hand_pose``), builds its bodies in a pybullet client, names
them for contact reports, and reports its state (cap angle, ball or object poses) as a flat
``{name: value}`` dict.  Positions are in metres, angles in radians.

Hand placements (palm frame ``P`` as in :mod:`handflow.plugins.simulator.hand_geometry`, wrist at ``HAND_BASE``):

- ``cap``, ``grasp``, ``empty``: palm facing down (palmar ``-y_P`` = world ``-z``), fingers along
  world ``+x``, thumb towards world ``+y``;
- ``balls``: palm facing up, fingers along world ``+x`` and tilted down by ``tilt_deg`` (thesis
  5.6.1: hand on a robot arm, palm up, tilted), thumb towards world ``-y``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from .bullet import pybullet as p
from .camera import CameraSpec

HAND_BASE = np.array([0.0, 0.0, 0.30])
"""World position of the wrist centre (the hand base link's origin) in every scene."""

PALM_DOWN = Rotation.from_matrix([[0, 0, 1], [1, 0, 0], [0, 1, 0]])
"""Palm frame in the world for palm-down scenes (columns: x_P, y_P, z_P)."""

PALM_UP = Rotation.from_matrix([[0, 0, 1], [-1, 0, 0], [0, -1, 0]])
"""Palm frame in the world for palm-up scenes before the tilt."""

BALL_COLOUR = (0.95, 0.75, 0.05, 1.0)
"""Both health balls are the same yellow (identical balls, thesis 5.6.2)."""
MARK_COLOURS = {"mark_a": (0.9, 0.05, 0.05, 1.0), "mark_b": (0.05, 0.7, 0.1, 1.0)}
"""Reference marks near the wrist: red ``mark_a`` normalises to (−1, 0), green ``mark_b`` to (1, 0)."""


@dataclass
class Scene:
    """Base class: no objects, hand palm-down in free space."""

    name: str = "empty"
    palm_thickness: float = 0.022  # set by the simulation from the hand's dimensions
    bodies: dict[tuple[int, int], str] = field(default_factory=dict, init=False)

    # -- placement ------------------------------------------------------------------------
    def hand_rotation(self) -> Rotation:
        return PALM_DOWN

    def hand_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """World position and quaternion (x, y, z, w) of the hand base link."""
        return HAND_BASE.copy(), self.hand_rotation().as_quat()

    def palm_to_world(self, points) -> np.ndarray:
        """Map points given in the (zero-wrist) palm frame to world coordinates."""
        return HAND_BASE + self.hand_rotation().apply(np.atleast_2d(np.asarray(points, dtype=float)))

    def camera(self) -> CameraSpec:
        """Camera above the palm looking at it; scenes override where the action is elsewhere."""
        centre = self.palm_to_world([0.0, -0.06, 0.08])[0]
        up = self.hand_rotation().apply([0.0, 0.0, 1.0])
        eye = self.palm_to_world([0.0, -0.35, 0.08])[0]
        return CameraSpec(tuple(eye), tuple(centre), tuple(up))

    def initial_posture(self) -> dict[str, float]:
        """Joint targets (by name) the hand starts with; unnamed joints start at 0 (clipped to limits)."""
        return {}

    # -- contents ------------------------------------------------------------------------
    def build(self, client: int, rng: np.random.Generator) -> None:
        """Create the scene's bodies in ``client``."""

    def before_step(self, client: int, t: float) -> None:
        """Called by :meth:`Simulation.step` before every physics step at simulated time ``t`` (s); no-op here."""

    def body_name(self, body: int, link: int) -> str:
        return self.bodies.get((body, link), self.bodies.get((body, -1), f"body{body}"))

    def state(self, client: int) -> dict[str, float]:
        return {}


def _cylinder(
    client: int, radius: float, height: float, rgba, pos, mass: float = 0.0, collide: bool = True, orn=(0, 0, 0, 1)
) -> int:
    col = (
        p.createCollisionShape(p.GEOM_CYLINDER, radius=radius, height=height, physicsClientId=client) if collide else -1
    )
    vis = p.createVisualShape(p.GEOM_CYLINDER, radius=radius, length=height, rgbaColor=rgba, physicsClientId=client)
    return p.createMultiBody(mass, col, vis, pos, orn, physicsClientId=client)


def _prism(radius: float, height: float, sides: int = 32) -> list[list[float]]:
    """Vertices of a convex regular prism (a cylinder's collision hull; Bullet's cylinder contacts jitter)."""
    a = np.linspace(0, 2 * np.pi, sides, endpoint=False)
    ring = np.c_[radius * np.cos(a), radius * np.sin(a)]
    return [[x, y, z] for z in (-height / 2, height / 2) for x, y in ring]


def schedule(name: str, value, form: tuple[str, ...], valid, rule: str) -> tuple[tuple[float, ...], ...]:
    """Parse a disturbance schedule ``[[time_s, …], …]`` (entries of the fields ``form``) sorted by
    time; a malformed entry, a non-finite number or an entry failing ``valid(*entry)`` raises
    ``ValueError`` naming ``rule``."""
    try:
        items = tuple(tuple(float(v) for v in entry) for entry in value)
        if any(len(entry) != len(form) for entry in items):
            raise ValueError
    except (TypeError, ValueError, OverflowError):  # OverflowError: float() of a huge integer
        raise ValueError(f"{name} must be a list of [{', '.join(form)}] entries, got {value!r}") from None
    if not np.isfinite(items).all():
        raise ValueError(f"{name} need finite numbers, got {value!r}")
    bad = [entry for entry in items if not (entry[0] >= 0 and valid(*entry))]
    if bad:
        raise ValueError(f"{name} need time_s >= 0 and {rule}, got {bad}")
    return tuple(sorted(items))


def lasting_schedule(name: str, value, quantity: str | None = None, low: float = 0.0, high: float = 0.0):
    """:func:`schedule` of disturbances that last: ``[time_s, duration_s]`` entries, or
    ``[time_s, duration_s, quantity]`` with ``low <= quantity <= high``; ``0 < duration_s <= 10``."""
    if quantity is None:
        return schedule(name, value, ("time_s", "duration_s"), lambda t, d: 0 < d <= 10, "0 < duration_s <= 10")
    return schedule(
        name,
        value,
        ("time_s", "duration_s", quantity),
        lambda t, d, q: 0 < d <= 10 and low <= q <= high,
        f"0 < duration_s <= 10 and {low:g} <= {quantity} <= {high:g}",
    )


class Timed:
    """Cursor over a schedule whose entries last ``entry[1]`` seconds: :meth:`poll` returns
    ``("start", entry)`` at the first call at or after an entry's time, ``("end", entry)`` at the
    first call at or after its end, else ``None``; one entry is active at a time (overlaps wait)."""

    def __init__(self, entries) -> None:
        self.entries, self.done, self.active = tuple(entries), 0, None

    def poll(self, t: float):
        if self.active is not None:
            entry = self.active
            if t >= self.started + entry[1] - 1e-9:
                self.active = None
                return "end", entry
            return None
        if self.done < len(self.entries) and t >= self.entries[self.done][0] - 1e-9:
            self.active, self.started = self.entries[self.done], t
            self.done += 1
            return "start", self.active
        return None


@dataclass
class CapScene(Scene):
    """Fixed bottle with a cap on a vertical revolute joint under the palm (docs/simulator.md).

    The cap turns against a constant friction torque (pybullet velocity motor with target 0 and
    force ``friction_torque``, the usual way to model joint friction) plus viscous ``damping``
    (N·m·s/rad, the thread's drag); ``cap_angle`` is the joint
    angle (unwrapped, positive = counter-clockwise seen from above).  The cap axis lies under the
    palm at ``centre_palm`` = (x_P, z_P); its top is ``top_below_palm`` below the palm surface.

    ``torques`` — disturbances ``[(time_s, duration_s, friction_torque), …]``: from the first
    physics step at or after ``time_s`` the thread's friction torque is ``friction_torque`` N·m
    for ``duration_s``, then back to ``friction_torque`` of the scene: a thread that binds for a
    moment (a large torque, e.g. 10 N·m, blocks the cap: the fingers cannot turn it) or a cap
    whose friction changes mid-turn.  ``torques_done`` in the state counts them.

    ``swaps`` — ``[(time_s, radius_m), …]``: bottle and cap are swapped for ones of radius
    ``radius_m`` (0.01–0.05 m) on the same axis, the cap keeping its angle and angular velocity —
    a cap of another size put under the hand mid-turn.  ``cap_radius`` in the state is the
    current radius, ``swaps_done`` counts the swaps.
    """

    name: str = "cap"
    radius: float = 0.025
    height: float = 0.02
    friction_torque: float = 0.06
    damping: float = 0.005
    lateral_friction: float = 1.0
    centre_palm: tuple[float, float] = (0.0, 0.085)
    top_below_palm: float = 0.035
    torques: tuple[tuple[float, float, float], ...] = ()
    swaps: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        if not 0.01 <= self.radius <= 0.05:
            raise ValueError(f"cap radius {self.radius} m is outside 0.01–0.05 m (the scenes use 0.015–0.035)")
        self.torques = lasting_schedule("torques", self.torques, "friction_torque", 0.0, 100.0)
        self.swaps = schedule(
            "swaps", self.swaps, ("time_s", "radius_m"), lambda t, r: 0.01 <= r <= 0.05, "0.01 <= radius_m <= 0.05"
        )
        self._torques = Timed(self.torques)

    def cap_top(self) -> np.ndarray:
        x, z = self.centre_palm
        return self.palm_to_world([x, -(self.palm_thickness / 2 + self.top_below_palm), z])[0]

    def camera(self) -> CameraSpec:
        top = self.cap_top()
        return CameraSpec(tuple(top + [0.28, -0.22, 0.10]), tuple(top + [0.0, 0.0, 0.01]), (0.0, 0.0, 1.0))

    def build(self, client: int, rng: np.random.Generator) -> None:
        self._torques = Timed(self.torques)
        self.swaps_done, self.thread_torque = 0, self.friction_torque
        self._build_bottle(client, self.radius)

    def _build_bottle(self, client: int, radius: float) -> None:
        """Bottle neck and cap of ``radius`` on the cap axis (the cap at angle 0, at rest)."""
        top = self.cap_top()
        neck_h = 0.06
        neck_pos = top - [0, 0, self.height + neck_h / 2]
        # the neck is flush with the cap: no rim a fingertip could hook under
        neck_col = p.createCollisionShape(p.GEOM_CYLINDER, radius=radius, height=neck_h, physicsClientId=client)
        neck_vis = p.createVisualShape(
            p.GEOM_CYLINDER, radius=radius, length=neck_h, rgbaColor=(0.6, 0.8, 0.9, 1), physicsClientId=client
        )
        cap_col = p.createCollisionShape(p.GEOM_MESH, vertices=_prism(radius, self.height), physicsClientId=client)
        cap_vis = p.createVisualShape(
            p.GEOM_CYLINDER,
            radius=radius,
            length=self.height,
            rgbaColor=(0.1, 0.35, 0.9, 1),
            physicsClientId=client,
        )
        body = p.createMultiBody(
            0.0,
            neck_col,
            neck_vis,
            neck_pos,
            linkMasses=[0.03],
            linkCollisionShapeIndices=[cap_col],
            linkVisualShapeIndices=[cap_vis],
            linkPositions=[[0, 0, neck_h / 2 + self.height / 2]],
            linkOrientations=[[0, 0, 0, 1]],
            linkInertialFramePositions=[[0, 0, 0]],
            linkInertialFrameOrientations=[[0, 0, 0, 1]],
            linkParentIndices=[0],
            linkJointTypes=[p.JOINT_REVOLUTE],
            linkJointAxis=[[0, 0, 1]],
            physicsClientId=client,
        )
        p.changeDynamics(
            body, 0, lateralFriction=self.lateral_friction, jointDamping=self.damping, physicsClientId=client
        )
        self.bottle, self.radius_now = body, radius
        self.bodies = {(body, -1): "bottle", (body, 0): "cap"}
        self.set_friction_torque(client, self.thread_torque)

    def _swap(self, client: int, radius: float) -> None:
        """Replace bottle and cap by ones of ``radius``; the cap keeps its angle and velocity."""
        angle, velocity, _, _ = p.getJointState(self.bottle, 0, physicsClientId=client)
        p.removeBody(self.bottle, physicsClientId=client)
        self._build_bottle(client, radius)
        p.resetJointState(self.bottle, 0, angle, velocity, physicsClientId=client)

    def set_friction_torque(self, client: int, torque: float) -> None:
        """Friction torque (N·m) of the cap's thread from now on."""
        self.thread_torque = float(torque)
        p.setJointMotorControl2(
            self.bottle, 0, p.VELOCITY_CONTROL, targetVelocity=0.0, force=self.thread_torque, physicsClientId=client
        )

    def before_step(self, client: int, t: float) -> None:
        """Start or end a due friction change (see ``torques``), make a due swap (see ``swaps``)."""
        event = self._torques.poll(t)
        if event is not None:
            kind, (_, _, torque) = event
            self.set_friction_torque(client, torque if kind == "start" else self.friction_torque)
        while self.swaps_done < len(self.swaps) and t >= self.swaps[self.swaps_done][0] - 1e-9:
            self._swap(client, self.swaps[self.swaps_done][1])
            self.swaps_done += 1

    def state(self, client: int) -> dict[str, float]:
        angle, velocity, _, _ = p.getJointState(self.bottle, 0, physicsClientId=client)
        return {
            "cap_angle": float(angle),
            "cap_velocity": float(velocity),
            "cap_radius": self.radius_now,
            "torques_done": float(self._torques.done),
            "swaps_done": float(self.swaps_done),
        }


@dataclass
class BallsScene(Scene):
    """Two equal health balls in a cupped palm of a palm-up, tilted hand; two coloured marks near the wrist.

    Documented choices (docs/simulator.md "Ball swapping"), all fields swappable:

    - **cupped palm**: a low static rim (``rim_height``) on the palm surface around ``cup_centre``
      (x_P, z_P) with inner radius ``2·ball_radius + cup_gap``, open over ``rim_opening_deg``
      (angles from ``+z_P`` towards ``+x_P``) at the finger end where the curled fingers close the cup.  Two balls in it always lie nearly
      diametrically, so their only free motion is circling around each other (Baoding balls) and
      a tangential push on one ball turns the pair;
    - ``tilt_deg`` lowers the fingertips (the balls lean on the fingers), ``side_tilt_deg > 0`` the
      thumb side; ball ``lateral_friction`` / ``rolling_friction`` / ``restitution``;
    - the balls start across the palm (ball 1 on the thumb side) with a seeded jitter of ``jitter`` m;
    - ``pushes`` — disturbances ``[(time_s, speed_m_s), …]`` fired by :meth:`before_step` at the
      first physics step at or after ``time_s``: the ball moving faster in the palm plane is set
      to ``speed`` against its direction of travel (both at rest: ball 1 along palm ``−z``,
      towards the wrist);
    - ``turns`` — disturbances ``[(time_s, angle_deg), …]``: at the first physics step at or after
      ``time_s`` the ball pair is turned by ``angle_deg`` about the cup centre in the palm plane
      (positive: counter-clockwise in the ``(x_P, z_P)`` plane, i.e. *back* against the clockwise
      swapping of :mod:`handflow.plugins.demo.ball_swap`) and both balls are stopped — a ball pushed back
      along its circular path by a finger, applied kinematically so it is exactly repeatable;
    - ``holds`` — disturbances ``[(time_s, duration_s), …]``: from the first physics step at or
      after ``time_s`` both balls are held where they are (positions frozen, velocities zeroed
      every physics step) for ``duration_s`` — a finger of the other hand pinning the balls for a
      moment while the hand goes on moving, so the balls fall behind the hand's phase;
    - ``frictions`` — ``[(time_s, duration_s, rolling_friction), …]``: both balls roll with
      ``rolling_friction`` (instead of the scene's) for ``duration_s`` — a sticky spill on the
      palm that slows the balls while the hand keeps its pace;
    - ``removals`` — ``[(time_s, duration_s), …]``: the ball nearer the finger end is taken out
      of the hand (parked out of view, 1 m below the hand) for ``duration_s`` while the other one
      stays and is moved by the hand alone; then it is put back where it fits, diametrically
      opposite the remaining ball about the cup centre (the pair nudged into contact, both at
      rest) — so the pair's phase is wherever the lone ball went, not where the hand is;
    - ``resizes`` — ``[(time_s, radius_m), …]``: both balls are swapped for a pair of radius
      ``radius_m`` (same density, same pair direction, in contact about the cup centre, at rest)
      — Baoding balls of another size put into the hand mid-cycle.

    State: world position of each ball (``ball1_x`` …) and of the two marks, ``pushes_done``,
    ``turns_done``, ``holds_done``, ``frictions_done``, ``removals_done``, ``resizes_done``.
    """

    name: str = "balls"
    ball_radius: float = 0.018
    ball_mass: float = 0.05
    lateral_friction: float = 0.6
    rolling_friction: float = 0.0002
    restitution: float = 0.1
    tilt_deg: float = 15.0
    side_tilt_deg: float = 0.0
    cup_centre: tuple[float, float] = (0.0, 0.068)
    cup_gap: float = 0.001
    rim_height: float = 0.012
    rim_opening_deg: tuple[float, float] = (-50.0, 50.0)
    jitter: float = 0.002
    pushes: tuple[tuple[float, float], ...] = ()
    turns: tuple[tuple[float, float], ...] = ()
    holds: tuple[tuple[float, float], ...] = ()
    frictions: tuple[tuple[float, float, float], ...] = ()
    removals: tuple[tuple[float, float], ...] = ()
    resizes: tuple[tuple[float, float], ...] = ()
    marks: dict[str, tuple[float, float]] = field(
        default_factory=lambda: {"mark_a": (0.03, 0.011), "mark_b": (-0.03, 0.011)}
    )

    def __post_init__(self) -> None:
        if not 0.01 <= self.ball_radius <= 0.03:
            raise ValueError(f"ball_radius {self.ball_radius} m is outside 0.01–0.03 m")
        self.pushes = schedule("pushes", self.pushes, ("time_s", "speed_m_s"), lambda t, v: v >= 0, "speed_m_s >= 0")
        self.turns = schedule(
            "turns", self.turns, ("time_s", "angle_deg"), lambda t, a: -180 <= a <= 180, "-180 <= angle_deg <= 180"
        )
        self.holds = lasting_schedule("holds", self.holds)
        self.removals = lasting_schedule("removals", self.removals)
        self.frictions = lasting_schedule("frictions", self.frictions, "rolling_friction", 0.0, 1.0)
        self.resizes = schedule(
            "resizes",
            self.resizes,
            ("time_s", "radius_m"),
            lambda t, r: 0.01 <= r <= self.ball_radius,
            f"0.01 <= radius_m <= ball_radius ({self.ball_radius}: a larger pair does not fit the cup)",
        )
        self._reset_disturbances()

    def _reset_disturbances(self) -> None:
        self.pushes_done = self.turns_done = self.resizes_done = 0
        self._holds, self._frictions, self._removals = Timed(self.holds), Timed(self.frictions), Timed(self.removals)
        self._held: np.ndarray | None = None
        self._parked: tuple[int, np.ndarray] | None = None
        self.radius_now = self.ball_radius

    def hand_rotation(self) -> Rotation:
        tilt = Rotation.from_euler("y", self.tilt_deg, degrees=True)
        side = Rotation.from_euler("x", self.side_tilt_deg, degrees=True)
        return side * tilt * PALM_UP

    def camera(self) -> CameraSpec:
        centre = self.palm_to_world([0.0, -self.palm_thickness / 2, 0.06])[0]
        eye = self.palm_to_world([0.0, -0.30, 0.06])[0]
        return CameraSpec(tuple(eye), tuple(centre), tuple(self.hand_rotation().apply([0.0, 0.0, 1.0])), fov_deg=40.0)

    def initial_posture(self) -> dict[str, float]:
        return {f"{f}_J{k}": 0.6 for f in ("FF", "MF", "RF", "LF") for k in (2, 3, 4)}

    @property
    def cup_radius(self) -> float:
        """Inner radius of the rim (m)."""
        return 2 * self.ball_radius + self.cup_gap

    def _build_rim(self, client: int, surface: float) -> int:
        """Static rim of box segments on the palm surface, open at the finger end (``+z_P``)."""
        thickness, n = 0.004, 16  # pybullet allows at most 16 shapes per compound shape
        radius = self.cup_radius + thickness / 2
        start, end = np.deg2rad(self.rim_opening_deg)
        angles = np.linspace(end, start + 2 * np.pi, n)  # angle from +z_P towards +x_P, around the closed part
        seg = radius * (angles[1] - angles[0]) * 1.05
        cx, cz = self.cup_centre
        rot = self.hand_rotation()
        shapes = dict(shapeTypes=[p.GEOM_BOX] * n, halfExtents=[[seg / 2, self.rim_height / 2, thickness / 2]] * n)
        frames = dict(
            collisionFramePositions=[
                list(rot.apply([cx + radius * np.sin(a), surface - self.rim_height / 2, cz + radius * np.cos(a)]))
                for a in angles
            ],
            collisionFrameOrientations=[list((rot * Rotation.from_euler("y", a)).as_quat()) for a in angles],
        )
        col = p.createCollisionShapeArray(**shapes, **frames, physicsClientId=client)
        vis = p.createVisualShapeArray(
            **shapes,
            rgbaColors=[[0.4, 0.42, 0.46, 1]] * n,
            visualFramePositions=frames["collisionFramePositions"],
            visualFrameOrientations=frames["collisionFrameOrientations"],
            physicsClientId=client,
        )
        rim = p.createMultiBody(0.0, col, vis, list(HAND_BASE), physicsClientId=client)
        p.changeDynamics(rim, -1, lateralFriction=0.2, restitution=self.restitution, physicsClientId=client)
        return rim

    def build(self, client: int, rng: np.random.Generator) -> None:
        surface = -self.palm_thickness / 2
        self.mark_ids = {}
        for name, (x, z) in self.marks.items():
            pos = self.palm_to_world([x, surface - 0.0006, z])[0]
            orn = (self.hand_rotation() * Rotation.from_euler("x", 90, degrees=True)).as_quat()
            self.mark_ids[name] = _cylinder(client, 0.006, 0.001, MARK_COLOURS[name], pos, collide=False, orn=orn)
        self.rim = self._build_rim(client, surface)
        self.bodies = {(self.rim, -1): "rim"}
        self.balls = []
        cx, cz = self.cup_centre
        for side in (1.0, -1.0):
            local = np.array(
                [cx + side * (self.ball_radius + self.cup_gap / 2), surface - self.ball_radius - 0.001, cz]
            )
            local[[0, 2]] += rng.uniform(-self.jitter, self.jitter, 2)
            self._add_ball(client, self.palm_to_world(local)[0], self.ball_radius)
        self._reset_disturbances()

    def _add_ball(self, client: int, pos, radius: float) -> None:
        """Create a ball of ``radius`` at world ``pos`` (mass scaled to the scene's ball density)."""
        col = p.createCollisionShape(p.GEOM_SPHERE, radius=radius, physicsClientId=client)
        vis = p.createVisualShape(p.GEOM_SPHERE, radius=radius, rgbaColor=BALL_COLOUR, physicsClientId=client)
        mass = self.ball_mass * (radius / self.ball_radius) ** 3
        ball = p.createMultiBody(mass, col, vis, list(pos), physicsClientId=client)
        p.changeDynamics(
            ball,
            -1,
            lateralFriction=self.lateral_friction,
            rollingFriction=self.rolling_friction,
            restitution=self.restitution,
            physicsClientId=client,
        )
        self.balls.append(ball)
        self.bodies[(ball, -1)] = f"ball{len(self.balls)}"

    # -- disturbance ---------------------------------------------------------------------
    def push(self, client: int, ball_index: int, velocity_world) -> None:
        """Set ball ``ball_index`` (0 or 1) to the linear velocity ``velocity_world`` (m/s, world frame)."""
        if ball_index not in (0, 1):
            raise ValueError(f"ball_index must be 0 or 1, got {ball_index}")
        p.resetBaseVelocity(
            self.balls[ball_index], linearVelocity=[float(v) for v in velocity_world], physicsClientId=client
        )

    def palm_plane_velocities(self, client: int) -> np.ndarray:
        """Ball velocities (2, 3) in the world with the palm-normal component removed."""
        normal = self.hand_rotation().apply([0.0, 1.0, 0.0])
        v = np.array([p.getBaseVelocity(b, physicsClientId=client)[0] for b in self.balls])
        return v - np.outer(v @ normal, normal)

    def turn_pair(self, client: int, angle_deg: float) -> None:
        """Turn the ball pair by ``angle_deg`` (counter-clockwise in ``(x_P, z_P)``) about the cup centre; stop both balls."""
        local = self.to_palm(self.ball_positions(client))
        centre = np.array(self.cup_centre)
        rel = local[:, [0, 2]] - centre
        a = np.deg2rad(angle_deg)
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        local[:, [0, 2]] = rel @ rot.T + centre
        for ball, pos in zip(self.balls, self.palm_to_world(local)):
            p.resetBasePositionAndOrientation(ball, pos.tolist(), [0, 0, 0, 1], physicsClientId=client)
            p.resetBaseVelocity(ball, [0, 0, 0], [0, 0, 0], physicsClientId=client)

    def _place(self, client: int, local) -> None:
        """Put both balls at palm-frame positions ``local`` (2, 3), at rest."""
        for ball, pos in zip(self.balls, self.palm_to_world(local)):
            p.resetBasePositionAndOrientation(ball, pos.tolist(), [0, 0, 0, 1], physicsClientId=client)
            p.resetBaseVelocity(ball, [0, 0, 0], [0, 0, 0], physicsClientId=client)

    def _pair_in_contact(self, direction, radius: float) -> np.ndarray:
        """Palm-frame positions (2, 3) of two touching balls of ``radius`` resting on the palm,
        centred on the cup centre, ball 1 along ``direction`` (x_P, z_P) from the centre."""
        u = np.asarray(direction, dtype=float)
        norm = np.linalg.norm(u)
        u = u / norm if norm > 1e-9 else np.array([0.0, -1.0])
        centre = np.array(self.cup_centre)
        y = -self.palm_thickness / 2 - radius - 0.001
        return np.array([[*c, y] for c in (centre + u * radius, centre - u * radius)])[:, [0, 2, 1]]

    def _remove_or_return(self, client: int, t: float) -> None:
        """Start or end a due removal (see ``removals``); keep a removed ball parked meanwhile."""
        event = self._removals.poll(t)
        if event is not None and event[0] == "start":
            z = self.to_palm(self.ball_positions(client))[:, 2]
            k = int(np.argmax(z))  # the ball nearer the finger end
            self._parked = (k, HAND_BASE + np.array([0.0, 0.0, -1.0]))
        elif event is not None:
            k = self._parked[0]
            self._parked = None
            stays = self.to_palm(self.ball_positions(client))[1 - k, [0, 2]]
            pair = self._pair_in_contact(stays - np.array(self.cup_centre), self.radius_now)
            self._place(client, pair if k == 1 else pair[::-1])
        if self._parked is not None:
            k, pos = self._parked
            p.resetBasePositionAndOrientation(self.balls[k], pos.tolist(), [0, 0, 0, 1], physicsClientId=client)
            p.resetBaseVelocity(self.balls[k], [0, 0, 0], [0, 0, 0], physicsClientId=client)

    def _resize(self, client: int, radius: float) -> None:
        """Swap the pair for balls of ``radius`` in contact about the cup centre, same direction, at rest."""
        local = self.to_palm(self.ball_positions(client))
        pair = self._pair_in_contact(local[0, [0, 2]] - local[1, [0, 2]], radius)
        for ball in self.balls:
            p.removeBody(ball, physicsClientId=client)
            del self.bodies[(ball, -1)]
        self.balls = []
        for pos in self.palm_to_world(pair):
            self._add_ball(client, pos, radius)
        self.radius_now = radius

    def before_step(self, client: int, t: float) -> None:
        """Fire every due disturbance (see the class docstring)."""
        event = self._holds.poll(t)
        if event is not None:
            self._held = self.to_palm(self.ball_positions(client)) if event[0] == "start" else None
        if self._held is not None:
            self._place(client, self._held)
        event = self._frictions.poll(t)
        if event is not None:
            rolling = event[1][2] if event[0] == "start" else self.rolling_friction
            for ball in self.balls:
                p.changeDynamics(ball, -1, rollingFriction=rolling, physicsClientId=client)
        self._remove_or_return(client, t)
        while self.resizes_done < len(self.resizes) and t >= self.resizes[self.resizes_done][0] - 1e-9:
            self._resize(client, self.resizes[self.resizes_done][1])
            self.resizes_done += 1
        while self.turns_done < len(self.turns) and t >= self.turns[self.turns_done][0] - 1e-9:
            self.turn_pair(client, self.turns[self.turns_done][1])
            self.turns_done += 1
        while self.pushes_done < len(self.pushes) and t >= self.pushes[self.pushes_done][0] - 1e-9:
            speed = self.pushes[self.pushes_done][1]
            v = self.palm_plane_velocities(client)
            norms = np.linalg.norm(v, axis=1)
            k = int(np.argmax(norms))
            if norms[k] > 1e-3:
                direction = -v[k] / norms[k]
            else:
                k, direction = 0, self.hand_rotation().apply([0.0, 0.0, -1.0])
            self.push(client, k, speed * direction)
            self.pushes_done += 1

    @property
    def removed(self) -> int | None:
        """Index of the ball taken out of the hand (``removals``), ``None`` when both are in."""
        return None if self._parked is None else self._parked[0]

    def ball_positions(self, client: int) -> np.ndarray:
        """World positions of the two balls (2, 3)."""
        return np.array([p.getBasePositionAndOrientation(b, physicsClientId=client)[0] for b in self.balls])

    def to_palm(self, points) -> np.ndarray:
        """World points (n, 3) in the palm frame (inverse of :meth:`palm_to_world`)."""
        return self.hand_rotation().inv().apply(np.atleast_2d(np.asarray(points, dtype=float)) - HAND_BASE)

    def palm_plane_positions(self, client: int) -> np.ndarray:
        """Ball centres (2, 2) in the palm plane, ``(x_P, z_P)`` (m): the input of
        :mod:`handflow.plugins.simulator.metrics`; NaN for a ball taken out (``removals``)."""
        out = self.to_palm(self.ball_positions(client))[:, [0, 2]]
        if self.removed is not None:
            out[self.removed] = np.nan
        return out

    def mark_positions(self) -> np.ndarray:
        """World positions of ``mark_a`` and ``mark_b`` (2, 3)."""
        surface = -self.palm_thickness / 2
        return self.palm_to_world([[x, surface, z] for x, z in self.marks.values()])

    def state(self, client: int) -> dict[str, float]:
        out: dict[str, float] = {}
        for name, pos in zip(
            ("ball1", "ball2", "mark_a", "mark_b"), np.vstack([self.ball_positions(client), self.mark_positions()])
        ):
            out.update({f"{name}_{axis}": float(v) for axis, v in zip("xyz", pos)})
        out["pushes_done"] = float(self.pushes_done)
        out["turns_done"] = float(self.turns_done)
        out["holds_done"] = float(self._holds.done)
        out["frictions_done"] = float(self._frictions.done)
        out["removals_done"] = float(self._removals.done)
        out["resizes_done"] = float(self.resizes_done)
        return out


GRASP_OBJECTS = {
    "box": (p.GEOM_BOX, {"halfExtents": [0.02, 0.08, 0.02]}, 0.04),
    "cylinder": (p.GEOM_CYLINDER, {"radius": 0.03, "height": 0.16}, 0.06),
    "sphere": (p.GEOM_SPHERE, {"radius": 0.03}, 0.06),
    "small_sphere": (p.GEOM_SPHERE, {"radius": 0.02}, 0.04),
    "thin_cylinder": (p.GEOM_CYLINDER, {"radius": 0.015, "height": 0.16}, 0.03),
}
"""Grasp objects (shape, pybullet dimensions, height as placed): those of thesis chapter 4 — box
4×4×16 cm, cylinder r 3 cm h 16 cm (lying, axis along world y), sphere r 3 cm — and the harder ones of
the evaluation grid (docs/grasping.md): a small sphere r 2 cm and a thin lying cylinder r 1.5 cm h 16 cm."""


@dataclass
class GraspScene(Scene):
    """One grasp object resting on a table under the palm-down hand (docs/simulator.md).

    ``position`` offsets the object from the point under the palm centre (world x, y in m) and
    ``yaw_deg`` turns it about the vertical.  Box and cylinder lie with their long axis along world
    ``y`` = the palm's ``x`` (across the fingers): thesis 4.3 ignores rotations about that axis for
    the cylinder, so that is its axis.  ``start_posture`` (joint name → rad) is where the hand starts,
    e.g. a grasp controller's pre-grasp.  The camera looks at the object from the little-finger side,
    slightly above the palm.  State: object position and roll/pitch/yaw.
    """

    name: str = "grasp"
    object: str = "box"
    position: tuple[float, float] = (0.0, 0.0)
    yaw_deg: float = 0.0
    mass: float = 0.1
    lateral_friction: float = 0.8
    gap_below_palm: float = 0.03
    start_posture: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.object not in GRASP_OBJECTS:
            raise ValueError(f"unknown grasp object '{self.object}'; choose one of {', '.join(GRASP_OBJECTS)}")

    def initial_posture(self) -> dict[str, float]:
        return dict(self.start_posture)

    def object_start(self) -> np.ndarray:
        """World position of the object's centre before the simulation starts."""
        height = GRASP_OBJECTS[self.object][2]
        centre = self.palm_to_world([0.0, 0.0, 0.06])[0]
        z = HAND_BASE[2] - self.palm_thickness / 2 - self.gap_below_palm - height / 2
        return np.array([centre[0] + self.position[0], centre[1] + self.position[1], z])

    def camera(self) -> CameraSpec:
        at = self.object_start() + [0.0, 0.0, 0.02]
        return CameraSpec(tuple(at + [0.0, -0.32, 0.08]), tuple(at), (0.0, 0.0, 1.0), fov_deg=45.0)

    def build(self, client: int, rng: np.random.Generator) -> None:
        kind, dims, height = GRASP_OBJECTS[self.object]
        pos = self.object_start()
        table_z = pos[2] - height / 2
        table_col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.3, 0.3, 0.01], physicsClientId=client)
        table_vis = p.createVisualShape(
            p.GEOM_BOX, halfExtents=[0.3, 0.3, 0.01], rgbaColor=(0.8, 0.8, 0.8, 1), physicsClientId=client
        )
        table = p.createMultiBody(
            0.0,
            table_col,
            table_vis,
            [pos[0] - self.position[0], pos[1] - self.position[1], table_z - 0.01],
            physicsClientId=client,
        )
        col = p.createCollisionShape(kind, physicsClientId=client, **dims)
        vis_dims = {("length" if k == "height" else k): v for k, v in dims.items()}  # visual API names it length
        vis = p.createVisualShape(kind, rgbaColor=(0.85, 0.3, 0.1, 1), physicsClientId=client, **vis_dims)
        lying = Rotation.from_euler("x", 90, degrees=True) if kind == p.GEOM_CYLINDER else Rotation.identity()
        orn = (Rotation.from_euler("z", self.yaw_deg, degrees=True) * lying).as_quat()
        self.object_id = p.createMultiBody(self.mass, col, vis, pos.tolist(), orn, physicsClientId=client)
        p.changeDynamics(self.object_id, -1, lateralFriction=self.lateral_friction, physicsClientId=client)
        self.bodies = {(table, -1): "table", (self.object_id, -1): self.object}

    def state(self, client: int) -> dict[str, float]:
        pos, orn = p.getBasePositionAndOrientation(self.object_id, physicsClientId=client)
        rpy = p.getEulerFromQuaternion(orn)
        return dict(
            zip(
                ("object_x", "object_y", "object_z", "object_roll", "object_pitch", "object_yaw"),
                map(float, (*pos, *rpy)),
            )
        )


SCENES: dict[str, type[Scene]] = {"empty": Scene, "cap": CapScene, "balls": BallsScene, "grasp": GraspScene}
"""Scene classes by name; options are the dataclass fields (e.g. ``{"radius": 0.02}`` for ``cap``)."""


def make_scene(name: str, options: dict | None = None) -> Scene:
    """Build scene ``name`` with ``options``; unknown names or options raise ``ValueError`` naming the valid ones."""
    if name not in SCENES:
        raise ValueError(f"unknown scene '{name}'; choose one of {', '.join(SCENES)}")
    cls = SCENES[name]
    allowed = {f for f in cls.__dataclass_fields__ if f not in ("name", "bodies", "palm_thickness")}
    unknown = set(options or {}) - allowed
    if unknown:
        raise ValueError(f"scene '{name}' has no option(s) {sorted(unknown)}; valid: {', '.join(sorted(allowed))}")
    opts = {k: tuple(v) if isinstance(v, list) else v for k, v in (options or {}).items()}
    return cls(**opts)
