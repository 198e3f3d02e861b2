"""Node ``simulator.robot_state``: the TF tree and robot description of a hand from its joint angles.

Like ROS's robot_state_publisher, for any of the three hand models (the human hand model from
the glove mapping, or a robot hand's commanded joints): input ``joints`` (JointState); outputs
``tf`` (Transforms: ``world_frame`` → base at ``origin``/``rpy``, then one transform per joint
by forward kinematics, :mod:`handflow.plugins.simulator.kinematics`) and ``description`` (the
viewer-safe URDF with the same frame prefix, at the first message and every
``description_period_s``); at most ``view_hz`` TF messages per second.  See docs/foxglove.md.
"""

from __future__ import annotations

from pydantic import Field
from scipy.spatial.transform import Rotation

from handflow.framework.files.params import StrictModel
from handflow.framework.messages import JointState, MessageError, Text, Transforms
from handflow.framework.plugin import Node

from .hand_geometry import build_skeleton
from .kinematics import HandKinematics, transforms_message
from .urdf import urdf_text


class RobotStateParams(StrictModel):
    """Parameters of ``simulator.robot_state``."""

    hand: str = Field("human", description="hand model: human | shadow | gifu")
    frame_prefix: str | None = Field(None, description="prefix of the hand's TF frames; default '<node id>/'")
    world_frame: str = Field("world", description="parent frame of the hand's base link")
    origin: tuple[float, float, float] = Field((0.0, 0.0, 0.0), description="base position in world_frame (m)")
    rpy: tuple[float, float, float] = Field((0.0, 0.0, 0.0), description="base roll, pitch, yaw in world_frame (rad)")
    description_period_s: float = Field(
        2.0, ge=0, description="republish the robot description this often (late viewers); 0 = only once"
    )
    view_hz: float = Field(30.0, gt=0, description="at most this many TF messages per second (viewers need no more)")


class RobotStateNode(Node):
    """Joint angles of a hand in; its TF tree (forward kinematics) and viewer-safe URDF out."""

    Params = RobotStateParams
    inputs = {"joints": JointState}
    outputs = {"tf": Transforms, "description": Text}

    def setup(self) -> None:
        prm = self.params
        skeleton = build_skeleton(prm.hand)
        prefix = prm.frame_prefix if prm.frame_prefix is not None else f"{self.ctx.node_id}/"
        self.kinematics = HandKinematics(skeleton, prefix)
        self.base_quaternion = Rotation.from_euler("xyz", prm.rpy).as_quat()
        self.description = Text(data=urdf_text(skeleton, viewer=True, prefix=prefix))
        self.last_description_ns: int | None = None
        self.last_tf_ns: int | None = None

    def on_message(self, port: str, msg: JointState) -> None:
        prm = self.params
        now = self.ctx.now_ns()
        if self.last_tf_ns is not None and now - self.last_tf_ns < 1e9 / prm.view_hz - 1e3:  # 1 µs slack
            return
        if msg.hand and msg.hand != prm.hand:
            raise MessageError(
                f"joints of hand '{msg.hand}' arrived; this node draws the '{prm.hand}' hand (param hand)"
            )
        try:
            frames = self.kinematics.transforms(msg.names, msg.positions)
        except ValueError as exc:  # unknown joint names: the runtime drops the message (docs/robustness.md)
            raise MessageError(str(exc)) from None
        base = self.kinematics.base
        tf = transforms_message(frames, prm.world_frame, base, prm.origin, self.base_quaternion)
        self.ctx.publish("tf", tf, stamp_ns=msg.header.stamp_ns)
        self.last_tf_ns = now
        last, period = self.last_description_ns, prm.description_period_s
        if last is None or (period > 0 and now - last >= period * 1e9):
            self.last_description_ns = now
            self.ctx.publish("description", self.description)
