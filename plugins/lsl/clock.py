"""LSL time ⇄ handflow stamps (docs/lsl.md).

LSL stamps are seconds of each host's ``local_clock()`` (a monotonic clock); an inlet with clock
synchronisation adds liblsl's estimate of the sender-to-receiver offset, giving seconds of this
host's ``local_clock()``.  handflow stamps are wall-clock nanoseconds, so both directions shift by
this host's wall-minus-LSL offset, measured when the samples are converted.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np


def wall_minus_lsl_ns(local_clock: Callable[[], float]) -> int:
    """``time.time_ns()`` minus ``local_clock()`` in ns (read back to back, the smaller gap of two tries)."""
    best = None
    for _ in range(2):
        t0 = time.time_ns()
        lsl = local_clock()
        t1 = time.time_ns()
        if best is None or t1 - t0 < best[0]:
            best = (t1 - t0, (t0 + t1) // 2 - round(lsl * 1e9))
    return best[1]


def lsl_to_stamps(timestamps: np.ndarray, offset_ns: int) -> np.ndarray:
    """handflow stamps (int64 ns) of LSL timestamps already in this host's LSL clock."""
    return np.round(np.asarray(timestamps, np.float64) * 1e9).astype(np.int64) + offset_ns


def stamp_to_lsl(stamp_ns: int, offset_ns: int) -> float:
    """The LSL timestamp (this host's ``local_clock`` seconds) of a handflow stamp."""
    return (stamp_ns - offset_ns) / 1e9
