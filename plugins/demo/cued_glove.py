"""``demo.cued_glove``: an emulated CyberGlove II whose hand performs the cued gesture (docs/tutorial_gestures.md).

The embedded emulator (byte for byte as ``glove.cyberglove``'s, :mod:`handflow.plugins.glove.node`)
plays a :class:`~.performer.CuedPerformer`: each ``Label`` on ``cue`` (``handflow collect``'s cue
topic) starts a new seeded performance of that gesture (``rest`` or ``""``: the relaxed hand).
Without cues it plays ``script`` (gesture, seconds; looped).  ``performed`` carries what the hand
performs, a ``Label`` at each change, stamped on the glove's clock: the ground truth of a live run.
"""

from __future__ import annotations

from pydantic import Field

from handflow.framework.messages import Label
from handflow.plugins.glove.node import CyberGloveNode

from .performer import CuedPerformer


class CuedGloveNode(CyberGloveNode):
    """Emulated CyberGlove II performing the gesture cued on ``cue`` (or a looped script) with seeded variation."""

    class Params(CyberGloveNode.Params):
        performer_seed: int = Field(0, description="seeds the variation between performances")
        noise: float = Field(0.5, ge=0, description="sensor noise of the emulated glove (raw units)")
        script: list[tuple[str, float]] = Field(
            default_factory=list, description="gesture, seconds … played (looped) while no cue has arrived"
        )

    inputs = {"cue": Label}
    outputs = {**CyberGloveNode.outputs, "performed": Label}

    def setup(self) -> None:
        if self.params.port != "emulator":
            raise ValueError(f"demo.cued_glove emulates its glove: 'port' must be 'emulator', got {self.params.port!r}")
        bad = [g for g, _ in self.params.script if not CuedPerformer.performs(g)]
        if bad or any(s <= 0 for _, s in self.params.script):
            raise ValueError(f"script: gestures {bad} unknown or a duration <= 0; steps are [gesture, seconds > 0]")
        self.performer = CuedPerformer(self.params.performer_seed, self.params.noise)
        self.cued = False
        self._script_step: int | None = None
        self._t0: int | None = None
        super().setup()

    def emulator_source(self):
        return self.performer.frame

    def _perform(self, label: str, index: int = 0) -> None:
        if not CuedPerformer.performs(label):
            self.ctx.log.error("cannot perform %r (it knows %s); resting instead", label, "grasp, wave, pinch, turn")
        self.performer.cue(label)
        self.ctx.publish("performed", Label(label=self.performer.label, index=index), stamp_ns=self.ctx.now_ns())

    def on_message(self, port: str, msg: Label) -> None:
        self.cued = True
        self._perform(msg.label, msg.index)

    def tick(self) -> None:
        script = self.params.script
        if script and not self.cued:
            now = self.ctx.now_ns()
            self._t0 = now if self._t0 is None else self._t0
            total = sum(s for _, s in script)
            t = ((now - self._t0) / 1e9) % total
            step = next(k for k, end in enumerate(_ends(script)) if t < end or k == len(script) - 1)
            if step != self._script_step:
                self._script_step = step
                self._perform(script[step][0], step)
        super().tick()


def _ends(script: list[tuple[str, float]]) -> list[float]:
    out, t = [], 0.0
    for _, s in script:
        t += s
        out.append(t)
    return out
