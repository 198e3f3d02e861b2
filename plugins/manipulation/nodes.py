"""Graph nodes of the manifold controllers (thin wrappers; docs/manipulation.md).

``manifold.open_loop`` (:class:`OpenLoopNode`), ``manifold.feedback_init``
(:class:`FeedbackInitNode`), ``manifold.closed_loop`` (:class:`ClosedLoopNode`).  Each reads the
manifold file named in its params (relative to the graph file), publishes joint targets on
``targets`` (JointState of the manifold's hand) and its latent position on ``latent``.

Fail-safe (declared): when the controller's observations go stale (nothing on its input for
``stale_after_s``) it publishes the open hand (:func:`~.safety.open_hand`) instead of continuing
blind, until observations resume; at shutdown the runtime publishes :meth:`safe_output` (the
open hand).  The open-loop controller has no observations, so only the shutdown case applies.
"""

from __future__ import annotations

from typing import Annotated, Literal, Optional

from pydantic import Field

from handflow.framework.files.inputs import InputPath
from handflow.framework.files.npz import format_check
from handflow.framework.files.params import StrictModel, live
from handflow.framework.messages import Contacts, JointState, LatentState, Points2D
from handflow.framework.plugin import Node
from handflow.plugins.manifold.io import FORMAT, FORMAT_VERSION

from .closed_loop import MASKS, ClosedLoopController
from .feedback_init import GraspByNavigation, latent_from_grasp, touching_fingers
from .manifold_file import ManipulationManifold
from .open_loop import OpenLoopController
from .safety import open_hand

_TRAIN = "train it with `handflow train configs/train/cap_*.yaml` (docs/manipulation.md)"
MANIFOLD = InputPath(
    what="manifold file",
    hint=_TRAIN,
    check=format_check("manipulation manifold", _TRAIN, (FORMAT, FORMAT_VERSION, "format_version")),
)


class _ControllerParams(StrictModel):
    manifold: Annotated[str, MANIFOLD] = Field(
        description="manifold file (.npz, from `handflow train`), relative to the graph"
    )
    rate_hz: float = Field(30.0, gt=0, description="control rate (one command per tick)")
    delta: float = live(0.02, gt=0, description="latent time step per control tick (speed)")
    safe_posture: dict[str, float] = Field(
        default_factory=dict, description="joint overrides of the open-hand fail-safe posture"
    )


class _ManifoldController(Node):
    """Shared plumbing: load the manifold, publish targets/latent, the fail-safe posture."""

    outputs = {"targets": JointState, "latent": LatentState}

    def setup(self) -> None:
        self.manifold = ManipulationManifold.load(self.ctx.resolve_path(self.params.manifold))
        self.last_input_ns: Optional[int] = None
        self.last_x = None
        self.stale = False

    def on_params(self, params, changed) -> None:
        """Speed (``delta``), closing step (``radius_step``) and horizon (``k``) while running (docs/tuning.md)."""
        super().on_params(params, changed)
        c = self.controller
        if "delta" in changed:
            c.delta = float(params.delta) * self.manifold.time_sign
        if "radius_step" in changed:  # keeps its direction (towards the small radius)
            c.radius_step = abs(float(params.radius_step)) * (1.0 if c.radius_step >= 0 else -1.0)
        if "k" in changed:
            c.k = int(params.k)

    def safe_output(self):
        return {"targets": open_hand(self.manifold.hand, self.params.safe_posture)} if hasattr(self, "manifold") else {}

    def publish_command(self, x, joints, error: float = 0.0) -> None:
        self.last_x = x
        self.ctx.publish(
            "targets", JointState(names=self.manifold.joint_names, positions=joints, hand=self.manifold.hand)
        )
        self.ctx.publish("latent", LatentState(manifold=self.manifold.kind, coords=x, error=error))

    def input_seen(self) -> None:
        self.last_input_ns = self.ctx.now_ns()
        if self.stale:
            self.ctx.log.info("observations resumed")
            self.stale = False

    def check_stale(self) -> bool:
        """True (and the open hand published) when observations are older than ``stale_after_s``."""
        now = self.ctx.now_ns()
        if self.last_input_ns is None:
            self.last_input_ns = now  # the grace period starts with the first tick
        if now - self.last_input_ns <= self.params.stale_after_s * 1e9:
            return False
        if not self.stale:
            self.ctx.log.warning(
                "no observation for %.2f s: publishing the open hand", (now - self.last_input_ns) / 1e9
            )
            self.stale = True
        self.ctx.publish("targets", open_hand(self.manifold.hand, self.params.safe_posture))
        return True


class OpenLoopParams(_ControllerParams):
    latent: list[float] = Field(
        description="start latent (one value per latent dimension); its "
        "non-time coordinates stay fixed (e.g. the radius)"
    )


class OpenLoopNode(_ManifoldController):
    """Open-loop latent navigation: fixed latent parameter, time advances by delta per tick."""

    plugin_name = "manipulation.open_loop"
    Params = OpenLoopParams

    def setup(self) -> None:
        super().setup()
        self.controller = OpenLoopController(self.manifold, self.params.latent, self.params.delta)

    def tick(self) -> None:
        self.publish_command(*self.controller.step())


class FeedbackInitParams(_ControllerParams):
    init: Literal["navigation", "grasp"] = Field(
        "navigation",
        description="navigation: grasp by closing along the radius (5.5.2); grasp: "
        "project the posture on input 'grasp' (5.5.1)",
    )
    radius_step: float = live(0.01, gt=0, description="latent radius per tick while closing")
    required_fingers: list[str] = Field(
        default_factory=lambda: ["TH", "FF", "MF"], description="segment-name prefixes that must touch"
    )
    contact_body: str = Field("cap", description="body name in the contacts that counts")
    contact_time: Optional[float] = Field(None, description="latent start time; default: the time of maximal closure")
    approach_s: float = Field(1.0, ge=0, description="hold the start posture this long first")
    overshoot: float = Field(
        0.25,
        ge=0,
        description="closing may go this fraction of the radius range "
        "past the small-radius border (extrapolated postures)",
    )
    regrasp: bool = Field(
        False, description="close again when the grip time per cycle halves (a closed loop on the radius)"
    )
    regrasp_fraction: float = Field(
        0.5, gt=0, lt=1, description="regrasp below this fraction of the first cycle's grip time"
    )
    stale_after_s: float = Field(0.5, gt=0, description="fail-safe: no contacts message for this long")


class FeedbackInitNode(_ManifoldController):
    """Feedback-initialised open loop (bottle cap): grasp by navigation or by posture projection, then turn."""

    plugin_name = "manipulation.feedback_init"
    Params = FeedbackInitParams
    inputs = {"contacts": Contacts, "grasp": JointState}

    def setup(self) -> None:
        super().setup()
        prm = self.params
        self.controller = GraspByNavigation(
            self.manifold,
            prm.delta,
            prm.radius_step,
            required=prm.required_fingers,
            approach_steps=int(round(prm.approach_s * prm.rate_hz)),
            contact_time=prm.contact_time,
            overshoot=prm.overshoot,
            regrasp=prm.regrasp,
            regrasp_fraction=prm.regrasp_fraction,
        )
        self.touching: set[str] = set()
        self.waiting_for_grasp = prm.init == "grasp"

    def on_message(self, port: str, msg) -> None:
        if port == "contacts":
            self.input_seen()
            self.touching = touching_fingers(msg, self.params.required_fingers, self.params.contact_body)
        elif self.waiting_for_grasp:
            x = latent_from_grasp(self.manifold, dict(zip(msg.names, msg.positions.tolist())))
            self.controller.x[:] = x
            self.controller.clock.value = float(x[self.manifold.time_dim])
            self.controller.start_turning(True)
            self.waiting_for_grasp = False
            self.ctx.log.info("grasp posture projected: latent %s", x.round(4).tolist())

    def tick(self) -> None:
        if self.check_stale() or self.waiting_for_grasp:
            return
        regrasps = self.controller.regrasps
        x = self.controller.update(self.touching)
        if self.controller.regrasps > regrasps:
            self.ctx.log.info("grip lost: closing again from latent radius %.4f", self.controller.radius)
        self.publish_command(x, self.controller.posture(x))


class ClosedLoopParams(_ControllerParams):
    k: int = live(5, ge=1, description="planned steps per observation (horizon k·delta)")
    mask: Literal[MASKS] = Field("ball1", description="partial projection on ball-1 dims (thesis) or both balls")
    tolerance: float = Field(
        0.05,
        ge=0,
        description="ball error above the best that still counts as consistent (0 = the thesis' pure projection)",
    )
    lag: float = Field(
        0.5, ge=0, description="keep the commanded phase while a consistent phase lies within this latent distance"
    )
    max_error: float = Field(
        0.1, gt=0, description="ball error above which the balls are off the manifold and the commanded phase is kept"
    )
    refractory: float = Field(
        0.0,
        ge=0,
        description="after a jump keep the commanded phase until the hand has advanced this latent distance (0 = off)",
    )
    stale_after_s: float = Field(0.5, gt=0, description="fail-safe: no ball observation for this long")


class ClosedLoopNode(_ManifoldController):
    """Closed-loop ball swapping: project observed balls, plan k steps of delta, actuate in order."""

    plugin_name = "manipulation.closed_loop"
    Params = ClosedLoopParams
    inputs = {"balls": Points2D}

    def setup(self) -> None:
        super().setup()
        prm = self.params
        self.controller = ClosedLoopController(
            self.manifold, prm.k, prm.delta, prm.mask, prm.tolerance, prm.lag, prm.max_error, refractory=prm.refractory
        )
        self.plan: list = []

    def on_message(self, port: str, msg: Points2D) -> None:
        result = self.controller.update(msg.points, msg.valid, self.last_x)
        if result is None:
            return
        self.input_seen()
        est, X, targets = result
        self.plan = [(x, q, est.error) for x, q in zip(X, targets)]
        self.publish_command(*self.plan.pop(0))

    def tick(self) -> None:
        if self.check_stale() or not self.plan:
            return
        self.publish_command(*self.plan.pop(0))
