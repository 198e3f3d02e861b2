"""Shared timing helper of the benchmark scripts: the median wall time of repeated calls."""

from __future__ import annotations

import statistics
import time


def median_time(fn, repeats: int) -> float:
    """Median seconds of ``repeats`` calls of ``fn()`` (the machines are shared: quote medians)."""
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def paced(rate: float, seconds: float):
    """Sequence numbers 1, 2, … of ``seconds`` at ``rate`` Hz, each yielded at its due time (sleeps,
    spinning the last 0.2 ms), from the first call on; a late one is yielded at once."""
    period, t_next = 1.0 / rate, time.perf_counter()
    for seq in range(1, int(seconds * rate) + 1):
        t_next += period
        while (d := t_next - time.perf_counter()) > 0:
            time.sleep(d if d > 2e-4 else 0)
        yield seq
