"""The experience-based grasp controller, a plain class (docs/grasping.md; thesis 4.1, Fig. 4.2).

One :meth:`ExperienceGraspController.step` per control cycle maps the measured posture and the set
of touching hand segments to joint targets:

(A) pre-grasp: actuate ``pregrasp`` until it is reached (or a contact occurs);
(B) no contact yet: approach the best match of the current posture (as a target shape, see
    :data:`STEER_MODES`); once it is reached without a contact, close further with the heuristic (D)
    and search the best match of the current posture again, approaching it when it changed —
    repeated until the first contact (the thesis rule; ``steer_before_contact=False`` closes with (D)
    only and lets experience enter with the first PCP match);
(C) per finger, by its contact state, re-matching with the PCP metric whenever the set of touching
    segments changes and the new set has persisted ``rematch_cycles`` cycles:
    - no contact → approach the best match's sub-target, once reached close with (D);
    - only non-tip contacts → hold the joints up to the touching segment, close the more distal
      ones with (D); no longer follows new best matches while it keeps a contact;
    - tip contact → hold the whole finger (until the tip contact is lost);
(D) closing heuristic (eq. 4.5, 4.6): closing joints advance at γ, the proximal one at λ·γ; a joint
    stops once a more distal segment of its finger touches.

Without an experience base the controller is the purely tactile baseline: (A) then (D)/(C) without
sub-targets.  Documented choices (all in :class:`ControllerConfig`):

- *hold* sets the held closing joints' targets to the measured angle (no push on a free object);
- *grip*: once every finger is finished (:meth:`~ExperienceGraspController.finished`), the held
  joints target ``squeeze`` beyond the measured angle — position-controlled joints press only with
  a target offset (phase ``"grip"``, targets fixed from then on);
- closing targets lead the measured angle by at most ``max_lead`` (bounded force when blocked);
- sub-targets are approached at ``approach_speed``, not jumped to (a position step would swing
  the finger at full motor speed into the object); ``synchronous_approach`` scales every joint's
  speed so that all joints of the hand arrive at the sub-target together (the fastest at
  ``approach_speed``), as a straight-line move to the matched posture — the fingers then meet the
  object at about the same time instead of one after the other;
- a (sub-)target is reached when every joint is within ``reach_tol`` or the finger stopped moving
  (``still_tol`` per cycle) — joint couplings can make exact targets unreachable;
- a lost contact still counts for ``release_cycles`` cycles, and a changed contact set must persist
  ``rematch_cycles`` cycles before it triggers a best-match search (contact flicker would otherwise
  re-match and re-steer the free fingers every cycle);
- ``steer``: which joints a best match moves, and in which direction (:data:`STEER_MODES`).
"""

from __future__ import annotations

from typing import Literal, get_args

import numpy as np
from pydantic import ConfigDict, Field

from handflow.framework.files.params import StrictModel

from .experience import ExperienceBase
from .hand_layout import Finger, HandLayout

SHADOW_PREGRASP = {"THJ5": -0.2, "THJ4": 1.22, "THJ1": 0.3}
"""Pre-grasp of the ShadowHand-like hand (thesis: one fixed pre-grasp for all runs): fingers straight,
thumb fully abducted (THJ4 at its limit, below the palm, opposing the fingers), turned slightly
towards them (THJ5 < 0 opposes in this model), tip slightly flexed; unnamed joints 0.  Chosen as the
best tactile pre-grasp of a 12-candidate sweep (THJ4 0.8–1.22 × THJ5 −0.4–0.2) on the evaluation grid
(docs/benchmarks.md, grasping pass 5): 91.7 % stable tactile grasps on 156 valid poses."""

SteerMode = Literal["closing", "blend", "staged", "all"]
STEER_MODES: tuple[str, ...] = get_args(SteerMode)
"""How a best match steers the free fingers (documented choice ``ControllerConfig.steer``):

- ``closing``: the match is a target shape for the *closing* joints only, approached only where
  it flexes further than the current targets (a match never opens a joint the heuristic closed);
  spread/rotation joints keep the pre-grasp, so they never swing into a floating object;
- ``blend``: like ``closing``, but the heuristic never waits for the match: each closing joint advances by
  the larger of the heuristic step and the (``approach_speed``-limited) step towards the match (before
  the first contact the best match is then searched every cycle);
- ``staged`` (default): ``closing`` before the first contact (phase B), from then on the match also sets
  the spread/rotation joints — associative completion: the contacts say where the object is, the
  match where the other fingers (the thumb's rotation above all) should be;
- ``all``: the literal thesis rule — every joint of the match, opening ones included.
"""

APPROACH, CLOSE, WRAP, HOLD = "approach", "close", "wrap", "hold"
"""Per-finger modes: moving to the sub-target, closing with the heuristic, non-tip contact, tip contact."""


class ControllerConfig(StrictModel):
    """Parameters of the controller (angles in rad, speeds in rad/s); also the ``grasp.experience`` node's."""

    model_config = ConfigDict(frozen=True)

    gamma: float = Field(1.0, gt=0, description="closing speed γ of the distal joints (rad/s)")
    lam: float = Field(1.0, gt=0, description="proximal joints close at λ·γ (λ > 1: marginal, λ ≈ 1: distinct flexion)")
    approach_speed: float = Field(1.0, gt=0, description="sub-targets are approached at most this fast per joint")
    synchronous_approach: bool = Field(False, description="all joints reach a new sub-target together")
    rate_hz: float = Field(60.0, gt=0, description="control cycles per second (dt of the closing heuristic)")
    reach_tol: float = Field(0.05, gt=0, description="a (sub-)target is reached within this error per joint …")
    still_tol: float = Field(0.002, gt=0, description="… or when no joint moved more than this in one cycle")
    squeeze: float = Field(0.1, ge=0, description="grip: held joints finally target the measured angle plus this")
    steer: SteerMode = Field("staged", description="how a best match steers the free fingers (STEER_MODES)")
    steer_before_contact: bool = Field(
        True, description="phase B approaches best matches (false: tactile until the first contact)"
    )
    rematch_cycles: int = Field(3, ge=0, description="a changed contact set must persist this many cycles to re-match")
    max_lead: float = Field(0.25, gt=0, description="closing targets lead the measured angle by at most this")
    release_cycles: int = Field(3, ge=0, description="a lost contact still counts for this many cycles")
    pregrasp: dict[str, float] = Field(default_factory=lambda: dict(SHADOW_PREGRASP), description="pre-grasp targets")


class ExperienceGraspController:
    """Phases A–D over the joints of ``layout``; ``experience=None`` gives the purely tactile baseline."""

    def __init__(
        self,
        layout: HandLayout,
        lower,
        upper,
        experience: ExperienceBase | None = None,
        config: ControllerConfig = ControllerConfig(),
    ) -> None:
        self.layout = layout
        self.config = config
        self.names = list(layout.names)
        self.index = {n: k for k, n in enumerate(self.names)}
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        unknown = sorted(set(config.pregrasp) - set(self.names))
        if unknown:
            raise ValueError(f"pre-grasp names joints {unknown} the hand '{layout.hand}' does not have")
        self.experience = experience
        if experience is not None:
            missing = [n for n in experience.names if n not in self.index]
            if missing:
                raise ValueError(
                    f"experience joints {missing} are not joints of hand '{layout.hand}'; "
                    f"use experience recorded with that hand"
                )
            self.exp_cols = np.array([self.index[n] for n in experience.names])
        self.fingers = layout.fingers
        self.finger_cols = {f.name: np.array([self.index[j] for j in f.joints]) for f in self.fingers}
        self.closing_mask = np.zeros(len(self.names), dtype=bool)
        self.closing_mask[[self.index[f.joints[c]] for f in self.fingers for c in f.closing]] = True
        self.reset()

    # -- state ---------------------------------------------------------------------------------
    def reset(self) -> None:
        """Start a new grasp at phase A."""
        self.phase = "A"
        pre = np.zeros(len(self.names))
        for n, v in self.config.pregrasp.items():
            pre[self.index[n]] = v
        self.pregrasp = np.clip(pre, self.lower, self.upper)
        self.targets = self.pregrasp.copy()
        self.touched: frozenset[str] = frozenset()
        self.matched_touch: frozenset[str] = frozenset()  # the contact set the current best match was searched for
        self.unchanged_for = 0  # cycles the contact set has stayed the same
        self.last_seen: dict[str, int] = {}
        self.mode = {f.name: APPROACH for f in self.fingers}
        self.deepest = {f.name: -1 for f in self.fingers}  # chain position of the deepest touching segment (wrap)
        self.match_index: int | None = None
        self.subtarget: np.ndarray | None = None
        self.approach_rate = np.full(len(self.names), self.config.approach_speed)  # per joint (rad/s)
        self.n_matches = 0
        self._new_sub = False
        self.q_prev: np.ndarray | None = None

    @property
    def dt(self) -> float:
        return 1.0 / self.config.rate_hz

    def _debounce(self, touched: frozenset[str]) -> frozenset[str]:
        """A contact counts until it has been absent for ``release_cycles`` cycles (contact flicker)."""
        for seg in touched:
            self.last_seen[seg] = 0
        for seg in list(self.last_seen):
            if seg not in touched:
                self.last_seen[seg] += 1
                if self.last_seen[seg] > self.config.release_cycles:
                    del self.last_seen[seg]
        return frozenset(self.last_seen)

    def hand_contacts(self, segments) -> frozenset[str]:
        """The touching segments that belong to a finger (palm contacts specify no joint)."""
        return frozenset(s for s in segments if self.layout.finger_of(s) is not None)

    # -- the control cycle ---------------------------------------------------------------------
    def step(self, q, touched_segments) -> np.ndarray:
        """One control cycle: measured posture ``q`` (hand order), touching segment names → targets."""
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.size != len(self.names):
            raise ValueError(f"posture has {q.size} joints, hand '{self.layout.hand}' has {len(self.names)}")
        touched = self._debounce(self.hand_contacts(touched_segments))
        moved = np.inf if self.q_prev is None else np.abs(q - self.q_prev)
        self.q_prev = q.copy()
        if self.phase == "A":
            if touched or self._reached(q, self.pregrasp, moved, np.arange(len(q))):
                self.phase = "B"
            else:
                return self.targets.copy()
        if self.phase == "B" and touched:
            self.phase = "C"
        if self.phase == "grip":
            return self.targets.copy()
        if self.phase == "B":
            self._first_contact(q, moved)
        else:
            self._contact_control(q, touched, moved)
            if self.finished(q):
                self.grip(q)
        self.touched = touched
        self.targets = np.clip(self.targets, self.lower, self.upper)
        return self.targets.copy()

    def _first_contact(self, q: np.ndarray, moved) -> None:
        """Phase B: approach the all-joint best match; close with (D) once it is reached."""
        approaching = any(m == APPROACH for m in self.mode.values()) and self.match_index is not None
        steering = self.experience is not None and self.config.steer_before_contact
        if steering and not approaching:  # re-match only once the last match is reached
            k, posture = self.experience.best_match(q[self.exp_cols])
            if k != self.match_index:
                self._set_match(k, posture)
                self.mode = {f.name: APPROACH for f in self.fingers}
        for f in self.fingers:
            self._free_finger(f, q, moved)

    def _contact_control(self, q: np.ndarray, touched: frozenset[str], moved) -> None:
        """Phase C: re-match on contact changes, then control every finger by its contact state."""
        self.unchanged_for = self.unchanged_for + 1 if touched == self.touched else 0
        settled = self.unchanged_for >= self.config.rematch_cycles
        if self.experience is not None and touched and touched != self.matched_touch and settled:
            mask = self.layout.pcp_mask(touched, self.experience.names)
            k, posture = self.experience.best_match(q[self.exp_cols], mask)
            self._set_match(k, posture)
            self.matched_touch = touched
        for f in self.fingers:
            mine = frozenset(s for s in touched if s in f.segments)
            if f.tip in mine:
                if self.mode[f.name] != HOLD:
                    self._hold(f, q, len(f.joints) - 1)
                    self.mode[f.name] = HOLD
            elif mine:
                deepest = max(f.segments[s] for s in mine)
                self.deepest[f.name] = deepest
                if self.mode[f.name] != WRAP or mine != frozenset(s for s in self.touched if s in f.segments):
                    self._hold(f, q, deepest)
                    self.mode[f.name] = WRAP
                self._close(f, q, mine)
            else:
                if self.mode[f.name] in (HOLD, WRAP) or self._new_sub:
                    self.mode[f.name] = APPROACH
                self._free_finger(f, q, moved)
        self._new_sub = False

    # -- building blocks -----------------------------------------------------------------------
    def _set_match(self, k: int, posture: np.ndarray) -> None:
        """The best match becomes the sub-target, restricted by ``config.steer`` (see :data:`STEER_MODES`)."""
        self.match_index = k
        self.n_matches += 1
        sub = self.targets.copy()
        sub[self.exp_cols] = posture
        if self.config.steer != "all":
            sub = np.where(self.closing_mask, np.maximum(sub, self.targets), sub)
            if self.config.steer in ("closing", "blend") or (self.phase == "B" and self.config.steer == "staged"):
                sub = np.where(self.closing_mask, sub, self.targets)
        self.subtarget = np.clip(sub, self.lower, self.upper)
        self.approach_rate = np.full(len(self.names), self.config.approach_speed)
        if self.config.synchronous_approach:
            gap = np.abs(self.subtarget - self.targets)
            self.approach_rate *= gap / max(float(gap.max()), 1e-9)
        self._new_sub = True

    def _free_finger(self, f: Finger, q: np.ndarray, moved) -> None:
        """A finger without contact: approach the sub-target at ``approach_speed``, then close with (D)."""
        cols = self.finger_cols[f.name]
        if self.config.steer == "blend" and self.subtarget is not None:
            before = self.targets[cols].copy()
            self.mode[f.name] = CLOSE
            self._close(f, q, frozenset())
            limit = self.approach_rate[cols] * self.dt
            pull = before + np.clip(self.subtarget[cols] - before, 0.0, limit)
            pull = np.minimum(pull, np.maximum(before, q[cols] + self.config.max_lead))
            self.targets[cols] = np.where(
                self.closing_mask[cols], np.maximum(self.targets[cols], pull), self.targets[cols]
            )
            return
        if self.mode[f.name] == APPROACH:
            if self.subtarget is None:
                self.mode[f.name] = CLOSE
            else:
                limit = self.approach_rate[cols] * self.dt
                gap = self.subtarget[cols] - self.targets[cols]
                if self.config.steer != "all":  # the heuristic may have closed past the match: never open
                    gap = np.where(self.closing_mask[cols], np.maximum(gap, 0.0), gap)
                self.targets[cols] += np.clip(gap, -limit, limit)
                if np.all(np.abs(gap) <= limit) and self._reached(q, self.targets, moved, cols):
                    self.mode[f.name] = CLOSE
        if self.mode[f.name] == CLOSE:
            self._close(f, q, frozenset())

    def _reached(self, q, target, moved, cols) -> bool:
        err = np.abs(np.clip(target[cols], self.lower[cols], self.upper[cols]) - q[cols])
        still = np.max(moved[cols]) < self.config.still_tol if np.ndim(moved) else False
        return bool(np.max(err) < self.config.reach_tol or still)

    def _hold(self, f: Finger, q: np.ndarray, upto: int) -> None:
        """Hold the closing joints of ``f`` up to chain position ``upto`` at the measured angle."""
        for c in f.closing:
            if c <= upto:
                j = self.index[f.joints[c]]
                self.targets[j] = q[j]

    def grip(self, q) -> np.ndarray:
        """Press: the touching fingers' closing joints target ``squeeze`` beyond ``q``.

        Called by :meth:`step` once :meth:`finished`, or by a driver whose time is up.
        """
        q = np.asarray(q, dtype=float)
        self.phase = "grip"
        for f in self.fingers:
            if self.mode[f.name] in (HOLD, WRAP):
                cols = [self.index[f.joints[c]] for c in f.closing]
                self.targets[cols] = q[cols] + self.config.squeeze
        self.targets = np.clip(self.targets, self.lower, self.upper)
        return self.targets.copy()

    def _close(self, f: Finger, q: np.ndarray, touching: frozenset[str]) -> None:
        """Phase D for finger ``f``: advance the closing joints not stopped by a more distal contact."""
        cfg = self.config
        deepest = max((f.segments[s] for s in touching), default=-1)
        first = f.closing[0]
        for c in f.closing:
            if c <= deepest:
                continue  # eq. 4.5: a more distal segment (or this one, held in phase C) touches
            j = self.index[f.joints[c]]
            speed = cfg.lam * cfg.gamma if c == first else cfg.gamma
            ahead = self.targets[j] + speed * self.dt
            self.targets[j] = min(ahead, max(self.targets[j], q[j] + cfg.max_lead))

    # -- progress ------------------------------------------------------------------------------
    def finished(self, q) -> bool:
        """Every finger holds a tip contact or cannot close further (limits reached / blocked)."""
        if self.phase == "grip":
            return True
        if self.phase != "C":
            return False
        q = np.asarray(q, dtype=float)
        for f in self.fingers:
            if self.mode[f.name] == HOLD:
                continue
            skip = self.deepest[f.name] if self.mode[f.name] == WRAP else -1
            cols = [self.index[f.joints[c]] for c in f.closing if c > skip]
            below_limit = self.targets[cols] < self.upper[cols] - 1e-6
            not_blocked = self.targets[cols] - q[cols] < self.config.max_lead - 1e-3
            free = below_limit & not_blocked
            if free.any():
                return False
        return True
