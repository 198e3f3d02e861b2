"""A hand that performs the gesture it is cued to, with seeded variation (the emulated glove of docs/tutorial_gestures.md).

:class:`CuedPerformer` switches its performance when cued: a new seeded :class:`~.gestures.Gesture`
of the cued class (every performance varies in timing and amplitude as ``gestures`` documents), or
:data:`REST_SPEC` for ``rest`` and the empty label, cross-fading from the posture it held over
``blend_s``.  Its raw glove frames are those of :class:`~handflow.plugins.glove.synthetic.SyntheticGlove`,
at the time of a clock (monotonic seconds), so it can feed a glove emulator from another thread.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from handflow.plugins.glove.synthetic import SyntheticGlove

from .gestures import GESTURES, SYMPATHETIC, Gesture, GestureSpec

REST_SPEC = GestureSpec("rest", 4.0, {k: (off, 0.15 * amp, lag) for k, (off, amp, lag) in SYMPATHETIC.items()})
"""The relaxed hand between cues: every joint moves a little (15 % of the sympathetic motion; documented
choice: a resting hand is not frozen, and a still stream would be trivially told from any gesture)."""
RESTING = ("rest", "", "unknown")


class CuedPerformer:
    """Performs the cued gesture: ``cue(label)`` switches, ``frame()`` is the raw glove frame now."""

    def __init__(
        self, seed: int = 0, noise: float = 0.5, blend_s: float = 0.4, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.rng = np.random.default_rng(seed)
        self.blend_s = blend_s
        self.clock = clock
        self.glove = SyntheticGlove(self, noise=noise, seed=seed)
        self.label = "rest"
        self._now = (Gesture(REST_SPEC, self._seed()), clock())
        self._before = self._now

    @staticmethod
    def performs(label: str) -> bool:
        """Whether ``label`` is a gesture this hand can perform (or rest)."""
        return label in GESTURES or label in RESTING

    def _seed(self) -> int:
        return int(self.rng.integers(2**31))

    def cue(self, label: str) -> None:
        """Perform ``label`` from now on (rest for ``rest``, ``""`` or a gesture it does not know)."""
        spec = GESTURES.get(label, REST_SPEC)
        self._before, self._now = self._now, (Gesture(spec, self._seed()), self.clock())
        self.label = label if label in GESTURES else "rest"

    def joints(self, t) -> np.ndarray:
        """Human-model postures at clock times ``t`` (the cross-fade from the previous performance included)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        (gesture, t0), (previous, p0) = self._now, self._before
        q = gesture.joints(np.maximum(t - t0, 0.0))
        w = np.clip((t - t0) / self.blend_s, 0.0, 1.0) if self.blend_s > 0 else np.ones_like(t)
        if (w < 1).any():
            w = (0.5 - 0.5 * np.cos(np.pi * w))[:, None]
            q = (1 - w) * previous.joints(np.maximum(t - p0, 0.0)) + w * q
        return q

    def frame(self, k: int = 0, t: float | None = None) -> np.ndarray:
        """The raw frame (22 values) at the clock's time now (emulator source signature; ``k``, ``t`` unused)."""
        return self.glove.frames(self.clock())[0]
