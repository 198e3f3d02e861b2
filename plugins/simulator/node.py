"""Node ``simulator.pybullet``: the :class:`~handflow.plugins.simulator.simulation.Simulation` on the runtime.

Input ``targets`` (JointState, any subset of the hand's joints; unknown names raise a clear error,
joints not named keep their last target).  Every tick (``rate_hz``) the node steps the physics so
that simulated time follows ``ctx.now_ns()`` (wall clock live, virtual time in lock-step replay),
then publishes ``joints`` (collision-corrected JointState), ``contacts`` (Contacts) and ``scene``
(Array with ``names``: the scene state plus ``sim_time`` and ``holding``); ``image`` (Image) at
``camera_hz``.  For 3D viewers (docs/foxglove.md) it also publishes ``tf`` (Transforms from
pybullet's link poses, every tick), ``markers`` (the scene's shapes, every tick) and ``description``
(the viewer-safe URDF, at start and every ``description_period_s``), frames under ``frame_prefix``;
``view_hz: 0`` turns the three off.
A tick that falls behind by more than ``max_catch_up_s`` skips the rest and warns, unless the
stall began within the first second of running (``START_UP_S``: the first publications and the
other processes' start on a busy machine; docs/simulator.md), which is logged at INFO.
Fail-safe: when no targets arrived for ``hold_safe_after_s`` since the last one the node
holds the last command, logs it once and reports ``holding = 1`` until targets resume (before
the first target it waits silently: start-up, not a fault).
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field

from handflow.framework.files.params import StrictModel
from handflow.framework.messages import Array, Contacts, Image, JointState, Markers, MessageError, Text, Transforms
from handflow.framework.plugin import Node

from .simulation import Simulation
from .urdf import urdf_text
from .viewer import scene_markers, simulated_hand_transforms

START_UP_S = 1.0
"""A stall that begins this soon after simulated time started is start-up, not lag: no WARNING."""


class SimulatorParams(StrictModel):
    """Parameters of ``simulator.pybullet``."""

    hand: Literal["human", "shadow", "gifu"] = Field("shadow", description="hand model")
    scene: Literal["empty", "cap", "balls", "grasp"] = Field("empty", description="scene")
    scene_options: dict[str, Any] = Field(
        default_factory=dict, description="scene fields, e.g. {radius: 0.02} (cap) or {pushes: [[20, 0.3]]} (balls)"
    )
    physics_hz: float = Field(240.0, gt=0, description="fixed physics rate")
    rate_hz: float = Field(60.0, gt=0, description="publish rate of joints/contacts/scene (tick rate)")
    camera_hz: float = Field(10.0, ge=0, description="image rate; 0 disables the camera")
    camera_width: int = Field(320, ge=8)
    camera_height: int = Field(240, ge=8)
    seed: int = 0
    hold_safe_after_s: float = Field(
        0.5, ge=0, description="hold the last command after this long without targets; 0 = never"
    )
    max_catch_up_s: float = Field(
        0.25, gt=0, description="at most this much simulated time per tick; a longer stall is skipped"
    )
    frame_prefix: str | None = Field(None, description="prefix of the hand's TF frames; default '<node id>/'")
    world_frame: str = Field("world", description="TF frame of the simulated world")
    view_hz: float = Field(30.0, ge=0, description="rate of tf and markers (at most the tick rate); 0 = off")
    description_period_s: float = Field(
        2.0, ge=0, description="republish the robot description this often (late viewers); 0 = only at start"
    )


class PybulletSimulatorNode(Node):
    """pybullet hand simulation: joint targets in; joints, contacts, scene state and camera images out."""

    Params = SimulatorParams
    inputs = {"targets": JointState}
    outputs = {
        "joints": JointState,
        "contacts": Contacts,
        "scene": Array,
        "image": Image,
        "tf": Transforms,
        "markers": Markers,
        "description": Text,
    }

    def setup(self) -> None:
        prm = self.params
        self.sim = Simulation(
            hand=prm.hand, scene=prm.scene, scene_options=prm.scene_options, seed=prm.seed, physics_hz=prm.physics_hz
        )
        self.t0_ns: int | None = None
        self.started_ns: int | None = None  # when simulated time started (t0_ns moves on a skip)
        self.last_advance_ns: int | None = None
        self.last_target_ns: int | None = None
        self.last_image_ns: int | None = None
        self.holding = False
        self.prefix = prm.frame_prefix if prm.frame_prefix is not None else f"{self.ctx.node_id}/"
        self.description = Text(data=urdf_text(self.sim.skeleton, viewer=True, prefix=self.prefix))
        self.last_description_ns: int | None = None
        self.last_view_ns: int | None = None

    def on_message(self, port: str, msg: JointState) -> None:
        try:
            self.sim.set_targets(msg.names, msg.positions)
        except ValueError as exc:  # unknown joint names: the runtime drops the message (docs/robustness.md)
            raise MessageError(str(exc)) from None
        self.last_target_ns = self.ctx.now_ns()
        if self.t0_ns is None:  # simulated time starts with the first event (message or tick)
            self.t0_ns = self.started_ns = self.last_target_ns
        if self.holding:
            self.ctx.log.info("targets resumed; leaving hold")
            self.holding = False

    def _advance(self, now: int) -> None:
        """Step the physics until simulated time catches up with ``now`` (bounded per tick)."""
        if self.t0_ns is None:
            self.t0_ns = self.started_ns = now - int(self.sim.time * 1e9)
        due = int((now - self.t0_ns) * self.sim.physics_hz / 1e9 + 1e-4) - self.sim.steps  # tolerate ns rounding
        limit = int(self.params.max_catch_up_s * self.sim.physics_hz)
        if due > limit:
            began = self.last_advance_ns if self.last_advance_ns is not None else self.started_ns
            start_up = began - self.started_ns < START_UP_S * 1e9
            (self.ctx.log.info if start_up else self.ctx.log.warning)(
                "simulation %d steps behind%s; skipping %.3f s",
                due,
                " at start-up" if start_up else "",
                (due - limit) / self.sim.physics_hz,
            )
            self.t0_ns += int((due - limit) * 1e9 / self.sim.physics_hz)
            due = limit
        self.last_advance_ns = now
        self.sim.step(max(due, 0))

    def _check_hold(self, now: int) -> None:
        hold = self.params.hold_safe_after_s
        since = self.last_target_ns
        if hold <= 0 or self.holding or since is None:  # before the first target: start-up, nothing to hold
            return
        if now - since > hold * 1e9:
            self.holding = True
            self.ctx.log.warning("no targets for %.2f s: holding the last command", (now - since) / 1e9)

    def tick(self) -> None:
        now = self.ctx.now_ns()
        self._advance(now)
        self._check_hold(now)
        self.ctx.publish("joints", self.sim.joint_state())
        self.ctx.publish("contacts", self.sim.contacts())
        state = self.sim.scene_state()
        state.update(sim_time=self.sim.time, holding=float(self.holding))
        self.ctx.publish("scene", Array(data=list(state.values()), names=list(state)))
        self._publish_viewer(now)
        cam = self.params.camera_hz
        if cam > 0 and (self.last_image_ns is None or now - self.last_image_ns >= 1e9 / cam - 1e3):  # 1 µs slack
            self.last_image_ns = now
            rgb = self.sim.render(self.params.camera_width, self.params.camera_height)
            self.ctx.publish("image", Image.from_array(rgb, frame_id=f"{self.params.scene}_camera"))

    def _publish_viewer(self, now: int) -> None:
        prm = self.params
        if prm.view_hz <= 0:
            return
        if self.last_view_ns is None or now - self.last_view_ns >= 1e9 / prm.view_hz - 1e3:  # 1 µs slack
            self.last_view_ns = now
            self.ctx.publish("tf", simulated_hand_transforms(self.sim, self.prefix, prm.world_frame))
            self.ctx.publish("markers", scene_markers(self.sim, prm.world_frame))
        period = prm.description_period_s
        last = self.last_description_ns
        if last is None or (period > 0 and now - last >= period * 1e9):
            self.last_description_ns = now
            self.ctx.publish("description", self.description)

    def teardown(self) -> None:
        sim = getattr(self, "sim", None)
        if sim is not None:
            sim.close()
