"""Disturbance classes of the manipulation evaluation and their recovery measures (docs/manipulation.md §5).

A class is one scene disturbance (:mod:`handflow.plugins.simulator.scenes`: the balls scene's
``turns``, ``pushes``, ``holds``, ``frictions``, ``removals``, ``resizes``; the cap scene's
``torques`` and ``swaps``) with fixed arguments, fired at a list of times.  :func:`schedule_times` draws the
times of one seed: the plan's nominal times each shifted by a seeded uniform offset within one
hand cycle, so seeds hit the hand at different phases.

**Recovery** (documented definition, :func:`recovery_times`): the progress rate (swaps, or cap
rotation) over the trailing ``window_s`` (the evaluation uses one hand cycle, 2 s) is followed
from the disturbance's start; if it never drops below ``fraction`` (50 %) of the same
controller's calm rate until one window after the disturbance's *end* (its time plus its
duration, 0 for instantaneous ones), the recovery time is 0; otherwise it is the delay from the
end until the rate is back at or above that level; searched up to ``within_s`` after the end,
otherwise the disturbance is a **failure** (not recovered, time ``inf``).  A disturbance counts as
recovered within one hand cycle when its recovery time is at most ``cycle_s``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DisturbanceClass:
    """Scene option ``option`` with entries ``[time_s, *args]``; ``duration_index``: which of
    ``args`` is the duration (``None``: instantaneous)."""

    scene: str
    option: str
    args: tuple[float, ...]
    duration_index: int | None
    doc: str

    @property
    def duration_s(self) -> float:
        return 0.0 if self.duration_index is None else float(self.args[self.duration_index])

    def scene_options(self, times_s) -> dict:
        """``{option: [[t, *args], …]}`` for the scene."""
        return {self.option: [[float(t), *self.args] for t in times_s]}


BALL_CLASSES = {
    "turn_back": DisturbanceClass("balls", "turns", (90.0,), None, "ball pair turned back by 90° (half a swap)"),
    "push": DisturbanceClass("balls", "pushes", (0.3,), None, "faster ball kicked at 0.3 m/s against its travel"),
    "hold": DisturbanceClass("balls", "holds", (1.0,), 0, "both balls pinned for 1 s while the hand moves on"),
    "friction": DisturbanceClass(
        "balls", "frictions", (2.0, 0.05), 0, "balls roll with rolling friction 0.05 (250×) for 2 s"
    ),
    "remove": DisturbanceClass(
        "balls", "removals", (1.0,), 0, "ball at the finger end taken out for 1 s, put back opposite the other"
    ),
    "resize": DisturbanceClass("balls", "resizes", (0.015,), None, "pair swapped for 15 mm balls (from 18 mm)"),
}
"""Ball-swap disturbance classes (arguments: docs/manipulation.md §5)."""

CAP_CLASSES = {
    "cap_block": DisturbanceClass("cap", "torques", (0.5, 10.0), 0, "cap blocked (10 N·m thread friction) for 0.5 s"),
    "cap_friction": DisturbanceClass(
        "cap", "torques", (2.0, 0.15), 0, "thread friction 0.15 N·m (2.5×) for one 2 s cycle"
    ),
    "cap_swap_small": DisturbanceClass(
        "cap", "swaps", (0.0175,), None, "cap swapped for a 1.75 cm one (from 2.5 cm) mid-turn, for good"
    ),
    "cap_swap_large": DisturbanceClass(
        "cap", "swaps", (0.0325,), None, "cap swapped for a 3.25 cm one (from 2.5 cm) mid-turn, for good"
    ),
}
"""Cap-turning disturbance classes."""


def schedule_times(nominal_s, seed: int, cycle_s: float) -> tuple[float, ...]:
    """The nominal times each shifted by a uniform offset in [0, ``cycle_s``) drawn from ``seed``
    (seed 0: no shift, the nominal times)."""
    nominal = np.asarray(nominal_s, dtype=float)
    if seed == 0:
        return tuple(nominal.tolist())
    offsets = np.random.default_rng(seed).uniform(0.0, cycle_s, nominal.size)
    return tuple((nominal + offsets).tolist())


def filled(progress) -> np.ndarray:
    """``progress`` with NaN samples (a ball out of the hand) holding the last finite value (0 before any)."""
    prog = np.asarray(progress, dtype=float)
    ok = np.isfinite(prog)
    idx = np.where(ok, np.arange(prog.size), 0)
    np.maximum.accumulate(idx, out=idx)
    out = prog[idx]
    out[~np.isfinite(out)] = 0.0
    return out


def recovery_times(
    times,
    progress,
    starts_s,
    ends_s,
    calm_rate_per_min: float,
    within_s: float = 10.0,
    window_s: float = 4.0,
    fraction: float = 0.5,
    direction: float = 1.0,
) -> np.ndarray:
    """Recovery time (s) after each disturbance (``starts_s``, ``ends_s``); ``inf`` = not
    recovered within ``within_s`` of its end (see the module docstring).  A calm rate of 0
    recovers nothing."""
    t = np.asarray(times, dtype=float)
    need = fraction * abs(calm_rate_per_min)
    out = np.full(len(ends_s), np.inf)
    if need <= 0:
        return out
    rate = direction * rate_over_time(t, progress, window_s)
    for i, (ts, te) in enumerate(zip(starts_s, ends_s)):
        dipped = np.flatnonzero((t >= ts) & (t <= te + window_s) & (rate < need))
        if dipped.size == 0:
            out[i] = 0.0
            continue
        back = np.flatnonzero((t > t[dipped[0]]) & (t <= te + within_s) & (rate >= need))
        if back.size:
            out[i] = max(t[back[0]] - te, 0.0)
    return out


def summarise(rec_times, cycle_s: float) -> dict:
    """``recovered_share`` (within one hand cycle), ``failures`` (never recovered), median
    ``recovery_s`` over the recovered ones (``None`` if none)."""
    rec = np.asarray(rec_times, dtype=float)
    ok = np.isfinite(rec)
    return {
        "recovered_share": float(np.mean(rec <= cycle_s)) if rec.size else 0.0,
        "failures": int(np.sum(~ok)),
        "recovery_s": float(np.median(rec[ok])) if ok.any() else None,
    }


def rate_over_time(times, progress, window_s: float) -> np.ndarray:
    """Progress rate per minute over the trailing ``window_s`` at every sample (for plots)."""
    t, prog = np.asarray(times, dtype=float), filled(progress)
    back = np.interp(t - window_s, t, prog, left=prog[0])
    span = np.minimum(t - t[0], window_s)
    return np.where(span > 0, 60.0 * (prog - back) / np.maximum(span, 1e-9), 0.0)
