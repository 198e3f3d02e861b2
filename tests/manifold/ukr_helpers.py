"""Shared data for the manifold tests (unique module name: tests dirs have no __init__)."""

import numpy as np

CYL_LATENT = [{"kernel": "periodic", "beta": 12, "time": True}, {"kernel": "gaussian", "beta": 4}]
RING_LATENT = [{"kernel": "periodic", "beta": 12, "time": True}]


def closed_curves(n_seq=4, noise=0.0, seed=0):
    """Noisy 3D closed curves (one periodic motion, several repetitions)."""
    rng = np.random.default_rng(seed)
    seqs = []
    for s in range(n_seq):
        n = 50 + 4 * s
        ph = 2 * np.pi * (np.arange(n) / n + rng.uniform())
        Y = np.c_[np.cos(ph) + 0.3 * np.cos(2 * ph), np.sin(ph) + 0.2 * np.sin(3 * ph), 0.5 * np.sin(ph)]
        seqs.append(Y + rng.normal(0, noise, Y.shape))
    return seqs
