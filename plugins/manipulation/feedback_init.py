"""Feedback-initialised open-loop control of the bottle cap (docs/manipulation.md; thesis 5.5).

:class:`GraspByNavigation` (5.5.2, preferred): start at a fixed latent point on the max-radius
border at a time where the fingers touch the cap, navigate towards decreasing radius (the hand
closes) until all ``required`` fingers have contact, freeze that radius, then navigate along time
(turning, repeated cycles).  :func:`latent_from_grasp` is the 5.5.1 variant: the radius comes
from projecting a grasp posture onto the manifold.

Documented choices (both swappable through the constructor):
- ``contact_time``: by default :func:`closure_time` — the middle of the closed phase on the
  max-radius border (the thesis picks it "by visual inspection or by analysing the finger
  contacts"; in the demonstrations thumb, index and middle finger touch the cap throughout the
  closed phase, while at its end — where the closure peaks — the sweep has moved the index
  finger away);
- which radius border is "max radius": :func:`open_side` — the border where the hand is more
  open (the learned manifold's radius axis has no fixed orientation);
- closing past the small-radius border (``overshoot``, default 0.25 of the radius range = 0.5 cm
  on the constructed manifold): a cap smaller than the smallest training radius needs a hand
  more closed than any demonstration, so the navigation goes on beyond the border and the
  postures there are extrapolated linearly (``ManipulationManifold.posture(extrapolate=True)``);
  ``overshoot=0`` stops at the border (the thesis' manifold has no postures beyond it).

``regrasp=True`` makes it a closed loop on the radius (ours, docs/manipulation.md §5): the
turning counts its control steps in which at least one required finger touches the cap (the
grip time); each time it comes back to the contact time (once per cycle of latent travel) it
compares the last cycle's grip time with that of the first cycle after the grasp, and when it
fell below ``regrasp_fraction`` of it (default ½) — the fingers have lost the cap, e.g. it was
swapped for a smaller one — the time stops and the closing goes on from the current radius until
all required fingers touch (the grasp by navigation again), then the turning resumes.  The
grip time, not the instantaneous contacts, is the measure because a cap can be turned by a
stroke whose contacts come and go: a 2 cm cap under the 2.5 cm posture is touched by the middle
finger alone and still turns ≈ 90° per cycle.
"""

from __future__ import annotations

import numpy as np

from handflow.plugins.hands.joints import HAND_MODELS

from .latent_time import LatentClock
from .manifold_file import ManipulationManifold

APPROACH, CLOSING, TURNING = "approach", "closing", "turning"


def _other_dim(manifold: ManipulationManifold) -> int:
    dims = [d for d in range(manifold.q) if d != manifold.time_dim]
    if len(dims) != 1:
        raise ValueError(
            f"feedback-initialised control needs a 2D (time, radius) manifold; this "
            f"one has latent dimensions {manifold.latent_names}"
        )
    return dims[0]


def flexion(manifold: ManipulationManifold, X) -> np.ndarray:
    """Closure measure of f(X) (M,): the summed finger and thumb flexion angles (joints whose
    description in the hand table says "flexion", without the wrist; positive closes)."""
    joints = HAND_MODELS[manifold.hand].joints
    flex = {j.name for j in joints if "flexion" in j.description and "wrist" not in j.description}
    cols = [k for k, n in enumerate(manifold.joint_names) if n in flex]
    return np.atleast_2d(manifold.posture(X))[:, cols].sum(axis=1)


def open_side(manifold: ManipulationManifold, n_grid: int = 64) -> float:
    """Latent radius value of the border where the hand is more open (mean over time)."""
    t, r = manifold.time_dim, _other_dim(manifold)
    times = np.linspace(*manifold.range(t), n_grid)
    means = []
    for border in manifold.range(r):
        X = np.zeros((n_grid, manifold.q))
        X[:, t], X[:, r] = times, border
        means.append(flexion(manifold, X).mean())
    return manifold.range(r)[int(np.argmin(means))]


def closure_time(manifold: ManipulationManifold, radius: float, fraction: float = 0.9, n_grid: int = 200) -> float:
    """Latent time in the middle of the closed phase at latent ``radius``: the centre of the
    contiguous time interval around the maximal closure where the closure stays at least
    ``fraction`` of its maximum."""
    t, r = manifold.time_dim, _other_dim(manifold)
    X = np.zeros((n_grid, manifold.q))
    X[:, t] = np.linspace(*manifold.range(t), n_grid)
    X[:, r] = radius
    flex = flexion(manifold, X)
    peak = int(np.argmax(flex))
    high = flex >= fraction * flex[peak]
    lo = peak - int(np.argmin(high[peak::-1])) + 1 if not high[: peak + 1].all() else 0
    hi = peak + int(np.argmin(high[peak:])) - 1 if not high[peak:].all() else n_grid - 1
    return float(X[(lo + hi) // 2, t])


class GraspByNavigation:
    """State machine approach → closing → turning; ``update(touching)`` returns the next latent.

    Parameters: ``delta`` latent time per step while turning (in the demonstrations' direction);
    ``radius_step`` latent radius per step while closing; ``required`` finger names that must all touch before turning;
    ``approach_steps`` steps holding the start posture first (lets the hand get there).
    ``overshoot`` latent radius beyond the small-radius border the closing may go (fraction of
    the radius range; postures there are extrapolated, see :meth:`posture`).  If the closing
    reaches that limit without the required contacts the radius is frozen there and
    ``grasp_complete`` stays False.  ``regrasp``, ``regrasp_fraction``: close again when the
    grip time per cycle drops below that fraction of the first cycle's (module docstring);
    ``regrasps`` counts those.
    """

    def __init__(
        self,
        manifold: ManipulationManifold,
        delta: float,
        radius_step: float,
        required=("TH", "FF", "MF"),
        approach_steps: int = 30,
        contact_time: float | None = None,
        start_radius: float | None = None,
        overshoot: float = 0.25,
        regrasp: bool = False,
        regrasp_fraction: float = 0.5,
    ) -> None:
        self.manifold = manifold
        self.t_dim, self.r_dim = manifold.time_dim, _other_dim(manifold)
        self.delta = float(delta) * manifold.time_sign
        self.required = frozenset(required)
        lo, hi = manifold.range(self.r_dim)
        r0 = open_side(manifold) if start_radius is None else float(start_radius)
        if not overshoot >= 0:
            raise ValueError(f"overshoot must be >= 0, got {overshoot}")
        self.r_end = lo - overshoot * (hi - lo) if abs(r0 - hi) <= abs(r0 - lo) else hi + overshoot * (hi - lo)
        self.radius_step = abs(float(radius_step)) * np.sign(self.r_end - r0)
        t0 = closure_time(manifold, r0) if contact_time is None else float(contact_time)
        self.clock = LatentClock(*manifold.range(self.t_dim), manifold.periodic, start=t0)
        self.x = np.zeros(manifold.q)
        self.x[self.t_dim], self.x[self.r_dim] = self.clock.value, r0
        self.state = APPROACH
        self.approach_left = int(approach_steps)
        self.grasp_complete = False
        if not 0 < regrasp_fraction < 1:
            raise ValueError(f"regrasp_fraction must lie in (0, 1), got {regrasp_fraction}")
        self.regrasp, self.regrasp_fraction, self.regrasps = bool(regrasp), float(regrasp_fraction), 0
        self._span = self.clock.hi - self.clock.lo
        self._travel, self._grip, self._grip_reference = 0.0, 0, None

    @property
    def radius(self) -> float:
        return float(self.x[self.r_dim])

    @property
    def cycles(self) -> int:
        return self.clock.cycles

    def posture(self, x) -> np.ndarray:
        """Joint targets of latent ``x`` (extrapolated beyond the radius border)."""
        return self.manifold.posture(x, extrapolate=True)

    def start_turning(self, complete: bool) -> None:
        self.state, self.grasp_complete = TURNING, complete

    def update(self, touching) -> np.ndarray:
        """One control step given the set of fingers currently touching the object."""
        if self.state == APPROACH:
            self.approach_left -= 1
            if self.approach_left <= 0:
                self.state = CLOSING
        elif self.state == CLOSING:
            if self.required <= set(touching):
                self.start_turning(True)
            else:
                r = self.radius + self.radius_step
                if (r - self.r_end) * np.sign(self.radius_step) >= 0:
                    r = self.r_end
                    self.start_turning(False)
                self.x[self.r_dim] = r
        elif self.regrasp and self._grip_lost(touching):
            self.state = CLOSING
            self.regrasps += 1
        else:
            self.x[self.t_dim] = self.clock.advance(self.delta)
        return self.x.copy()

    def _grip_lost(self, touching) -> bool:
        """Count the grip time; at the end of each cycle of travel, has it dropped below
        ``regrasp_fraction`` of the first cycle's since the last grasp?"""
        self._grip += bool(self.required & set(touching))
        self._travel += abs(self.delta)
        if self._travel < self._span - 1e-12:
            return False
        grip, self._grip, self._travel = self._grip, 0, self._travel - self._span
        if self._grip_reference is None:
            self._grip_reference = grip
            return False
        if grip >= self.regrasp_fraction * self._grip_reference:
            return False
        self._grip_reference = None
        return True


def touching_fingers(contacts, fingers=("TH", "FF", "MF"), body: str = "cap") -> set[str]:
    """Which of ``fingers`` (segment-name prefixes) touch ``body`` in a Contacts message."""
    return {f for f in fingers for seg, b in zip(contacts.segments, contacts.bodies) if b == body and seg.startswith(f)}


def latent_from_grasp(manifold: ManipulationManifold, joints: dict[str, float]) -> np.ndarray:
    """5.5.1: project a grasp posture (joint name → rad) onto the manifold; its radius coordinate
    parameterises the turning that starts from the projected latent."""
    return manifold.project_posture(joints)
