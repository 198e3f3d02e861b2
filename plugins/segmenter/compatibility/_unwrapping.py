"""Latent unwrapping: spikes bridged, steps wrapped into one latent period (docs/segmentation.md)."""

from __future__ import annotations

import numpy as np

SPIKE_STEP = 0.25 * np.pi  # observations this far from both ends of their run make a spike
SPIKE_LENGTH = 2  # the longest spike (observations) that is bridged; docs/segmentation.md


def wrapped_step(step: np.ndarray) -> np.ndarray:
    """Latent steps wrapped into ``[−π/2, π/2)`` (latent period π)."""
    return np.mod(step + 0.5 * np.pi, np.pi) - 0.5 * np.pi


def bridged_latent(latent_time: np.ndarray) -> np.ndarray:
    """Latent times (N, …) with every *spike* bridged (axis 0).

    Documented choice (docs/segmentation.md): a spike is a run of up to :data:`SPIKE_LENGTH`
    observations whose projections all lie more than a quarter period (:data:`SPIKE_STEP`) away
    from the observations just before and just after the run, while those two lie less than that
    apart; the run is moved onto the straight line between them.  A projection that lands briefly
    on another branch of the manifold (near a crossing, or at the stroke's seam) would otherwise
    add or remove a whole period of progress.  The first and the last observation are kept.
    """
    lt = np.array(latent_time, dtype=float, copy=True)
    raw = lt.copy()
    n = lt.shape[0]
    for length in range(1, SPIKE_LENGTH + 1):
        if n < length + 2:
            break
        before, after = raw[: n - length - 1], raw[length + 1 :]
        bridge = wrapped_step(after - before)
        spike = np.abs(bridge) < SPIKE_STEP
        for i in range(length):
            here = raw[1 + i : n - length + i]
            spike &= (np.abs(wrapped_step(here - before)) > SPIKE_STEP) & (
                np.abs(wrapped_step(after - here)) > SPIKE_STEP
            )
        for i in range(length):
            lt[1 + i : n - length + i] = np.where(
                spike, np.mod(before + bridge * (i + 1) / (length + 1), np.pi), lt[1 + i : n - length + i]
            )
    return lt


def unwrapped_latent(latent_time: np.ndarray) -> np.ndarray:
    """Latent path: the steps of :func:`bridged_latent`, each wrapped into ``[−π/2, π/2)``, summed
    (axis 0)."""
    return _path(bridged_latent(latent_time))


def _path(bridged: np.ndarray) -> np.ndarray:
    """:func:`unwrapped_latent` of latent times already bridged."""
    steps = wrapped_step(np.diff(bridged, axis=0))
    return np.concatenate([np.zeros((1,) + steps.shape[1:]), np.cumsum(steps, axis=0)])


ORDER_PATHS = ("unwrapped", "direct")
