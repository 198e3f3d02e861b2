"""Node ``grasp.experience``: the experience-based grasp controller on the runtime (docs/grasping.md).

Inputs: ``joints`` (JointState, the simulator's collision-corrected posture), ``contacts`` (Contacts),
``trigger`` (Label, optional: ``grasp`` restarts a grasp from phase A, ``release`` opens to the
pre-grasp and waits).  Every tick (``rate_hz`` = the control rate) the node runs one control cycle on
the latest posture and contacts and publishes ``targets`` (JointState for the simulator) and
``status`` (Status: phase, number of best-match searches, touching segments).  Contacts with
``ignore_bodies`` (the table) are not grasp contacts.  The experience base is a SOM file, a grasp
dataset (raw database) or nothing (purely tactile grasping).
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field

from handflow.framework.files.inputs import InputPath
from handflow.framework.messages import Contacts, JointState, Label, MessageError, Status
from handflow.framework.plugin import Node
from handflow.plugins.hands.joints import HAND_MODELS

from .controller import SHADOW_PREGRASP, ControllerConfig, ExperienceGraspController
from .experience import EXPERIENCE_HINT, ExperienceBase
from .hand_layout import hand_layout


class ExperienceGraspParams(ControllerConfig):
    """Parameters of ``grasp.experience``: the controller's (declared once, in :class:`ControllerConfig`) and the node's."""

    hand: Literal["shadow", "gifu", "human"] = Field("shadow", description="hand model")
    experience: Annotated[str, InputPath(what="grasp experience file", hint=EXPERIENCE_HINT)] | None = Field(
        None, description="SOM (.npz from grasp-som) or grasp dataset; none = tactile only"
    )
    pregrasp: dict[str, float] | None = Field(None, description="pre-grasp joint targets (default: the hand's)")
    ignore_bodies: list[str] = Field(
        default_factory=lambda: ["table"], description="bodies whose contacts do not count"
    )
    autostart: bool = Field(True, description="start grasping at once (else wait for a 'grasp' trigger)")


class ExperienceGraspNode(Node):
    """Experience-based grasping: posture and contacts in, joint targets out (phases A–D)."""

    Params = ExperienceGraspParams
    inputs = {"joints": JointState, "contacts": Contacts, "trigger": Label}
    outputs = {"targets": JointState, "status": Status}

    def setup(self) -> None:
        prm = self.params
        if prm.hand not in HAND_MODELS:
            raise ValueError(f"unknown hand '{prm.hand}'; choose one of {', '.join(HAND_MODELS)}")
        model = HAND_MODELS[prm.hand]
        experience = ExperienceBase.load(self.ctx.resolve_path(prm.experience)) if prm.experience else None
        pregrasp = prm.pregrasp if prm.pregrasp is not None else (SHADOW_PREGRASP if prm.hand == "shadow" else {})
        controller_fields = set(ControllerConfig.model_fields) - {"pregrasp"}
        config = ControllerConfig(**prm.model_dump(include=controller_fields), pregrasp=dict(pregrasp))
        self.controller = ExperienceGraspController(hand_layout(prm.hand), model.lower, model.upper, experience, config)
        self.model = model
        self.posture: np.ndarray | None = None
        self.touched: list[str] = []
        self.active = prm.autostart

    def on_message(self, port: str, msg) -> None:
        if port == "joints":
            where = {n: k for k, n in enumerate(msg.names)}
            missing = [n for n in self.controller.names if n not in where]
            if missing:
                raise MessageError(
                    f"joint state lacks joints {missing} of hand '{self.params.hand}'; "
                    f"connect the simulator's 'joints' output of the same hand"
                )
            self.posture = np.asarray(msg.positions, dtype=float)[[where[n] for n in self.controller.names]]
        elif port == "contacts":
            ignore = set(self.params.ignore_bodies)
            self.touched = [s for s, b in zip(msg.segments, msg.bodies) if b not in ignore]
        elif port == "trigger":
            if msg.label == "grasp":
                self.controller.reset()
                self.active = True
            elif msg.label == "release":
                self.controller.reset()
                self.active = False
            else:
                self.ctx.log.warning("trigger label %r ignored; use 'grasp' or 'release'", msg.label)

    def tick(self) -> None:
        ctl = self.controller
        if self.posture is None:
            return
        targets = ctl.step(self.posture, self.touched) if self.active else ctl.pregrasp
        self.ctx.publish(
            "targets",
            JointState(names=list(ctl.names), positions=np.asarray(targets, dtype=float), hand=self.model.name),
        )
        phase = ctl.phase if self.active else "idle"
        self.ctx.publish(
            "status",
            Status(
                state=phase,
                counters={"matches": float(ctl.n_matches), "contacts": float(len(ctl.touched))},
                text=",".join(sorted(ctl.touched)),
            ),
        )
