"""Graph nodes of the mapping family (thin wrappers; the science lives in human.py / robot.py).

- ``mapping.human_hand``: ``raw`` GloveFrame → ``joints`` JointState (24 human-model joints);
  params ``profile`` and ``calibration`` (paths relative to the graph file; defaults ship in
  configs/glove/; read by the preflight, docs/pipelines.md "Inputs").
- ``mapping.shadow_hand`` / ``mapping.gifu_hand``: ``joints`` human JointState → ``joints`` robot
  JointState.  Input joints are matched by name (any order); a message lacking a human joint is
  dropped by the runtime with a rate-limited error naming it (docs/robustness.md).

Every output message carries the joint names and keeps the input's stamp.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Annotated, Literal

import numpy as np

from handflow.framework.files.inputs import InputPath
from handflow.framework.files.params import StrictModel, live
from handflow.framework.messages import GloveFrame, JointState, MessageError
from handflow.framework.plugin import Node
from handflow.plugins.hands.joints import HUMAN
from handflow.plugins.hands.sensors import N_SENSORS

from .calibration import DEFAULT_CALIBRATION, DEFAULT_PROFILE, load_calibration, load_profile
from .human import HumanHandMapping
from .robot import GifuHandMapping, RobotHandMapping, ShadowHandMapping


class HumanHandMappingNode(Node):
    """Raw CyberGlove frames → 24 joints of the human hand model (docs/glove.md)."""

    class Params(StrictModel):
        profile: Annotated[str, InputPath(what="glove profile", check=load_profile)] = str(DEFAULT_PROFILE)
        calibration: Annotated[str, InputPath(what="session calibration", check=load_calibration)] = live(
            str(DEFAULT_CALIBRATION),
            description="session calibration file (after `handflow calibrate`, set it while running)",
        )
        handedness: Literal["right", "left"] = "right"

    inputs = {"raw": GloveFrame}
    outputs = {"joints": JointState}

    def setup(self) -> None:
        self.mapping = self._mapping(self.params)

    def _mapping(self, p: Params) -> HumanHandMapping:
        return HumanHandMapping(
            load_profile(self.ctx.resolve_path(p.profile)), load_calibration(self.ctx.resolve_path(p.calibration))
        )

    def on_params(self, params: Params, changed: frozenset[str]) -> None:
        """A new calibration file while running (docs/tuning.md); one that does not load is refused."""
        mapping = self._mapping(params)
        super().on_params(params, changed)
        self.mapping = mapping

    def on_message(self, port: str, msg: GloveFrame) -> None:
        if msg.sensors.size != N_SENSORS:  # the runtime drops and counts it (docs/robustness.md)
            raise MessageError(f"a glove frame needs {N_SENSORS} sensor values, got {msg.sensors.size}")
        q = self.mapping.map(msg.sensors)
        self.ctx.publish(
            "joints",
            JointState(names=HUMAN.names, positions=q, hand=HUMAN.name, handedness=self.params.handedness),
            stamp_ns=msg.header.stamp_ns,
        )


class _RobotNode(Node, ABC):
    inputs = {"joints": JointState}
    outputs = {"joints": JointState}

    @abstractmethod
    def _make(self) -> RobotHandMapping:
        """The robot mapping built from the params."""

    def setup(self) -> None:
        self.mapping = self._make()
        self._order: tuple[list[str], np.ndarray] | None = None

    def _human_vector(self, msg: JointState) -> np.ndarray:
        if self._order is None or self._order[0] != msg.names:
            index = {n: i for i, n in enumerate(msg.names)}
            missing = [n for n in HUMAN.names if n not in index]
            if missing:
                raise MessageError(
                    f"input JointState lacks human-model joints {', '.join(missing)}; connect it to mapping.human_hand"
                )
            self._order = (list(msg.names), np.array([index[n] for n in HUMAN.names]))
        return msg.positions[self._order[1]]

    def on_message(self, port: str, msg: JointState) -> None:
        q = self._human_vector(msg)
        model = self.mapping.model
        self.ctx.publish(
            "joints",
            JointState(names=model.names, positions=self.mapping.map(q), hand=model.name, handedness=msg.handedness),
            stamp_ns=msg.header.stamp_ns,
        )


class ShadowHandMappingNode(_RobotNode):
    """Human-model joints → ShadowHand-like 24 joints (analytic thumb base, docs/glove.md)."""

    class Params(StrictModel):
        theta0_at_singularity: float = 0.0

    def _make(self) -> RobotHandMapping:
        return ShadowHandMapping(self.params.theta0_at_singularity)


class GifuHandMappingNode(_RobotNode):
    """Human-model joints → Gifu-like hand (16 DOF; PIP/DIP merged)."""

    class Params(StrictModel):
        merge: Literal["mean", "pip", "max"] = "mean"
        theta0_at_singularity: float = 0.0

    def _make(self) -> RobotHandMapping:
        return GifuHandMapping(self.params.merge, self.params.theta0_at_singularity)
