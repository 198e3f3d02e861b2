"""Synthetic cap-turning-like sequences for the manipulation tests (unique module name)."""

import numpy as np

RADII_CM = (1.5, 2.0, 2.5, 3.0, 3.5)


def posture(phase, radius_cm):
    """A 6-D 'hand posture' on one motion cycle (phase in [0, 1]); closure shrinks with r."""
    a = 2 * np.pi * np.asarray(phase, dtype=float)
    closure = 1.6 - 0.3 * radius_cm
    return np.c_[
        np.cos(a),
        0.8 * np.sin(a),
        closure * (0.5 - 0.5 * np.cos(a)),
        0.4 * np.sin(2 * a),
        closure * np.sin(a) ** 2,
        0.2 * np.cos(3 * a),
    ]


def warped_phases(n, rng, warp=0.5):
    """n chronological phases over one complete cycle with a random monotone timing warp."""
    u = np.linspace(0.0, 1.0, n)
    w = rng.uniform(-warp, warp)
    return np.clip(u + w * np.sin(np.pi * u) * u, 0.0, 1.0)


def cap_sequences(radii=RADII_CM, per_radius=3, seed=0, noise=0.01):
    """(sequences, radii, true phases) with varying lengths and timing per sequence."""
    rng = np.random.default_rng(seed)
    seqs, rs, phases = [], [], []
    for r in radii:
        for _ in range(per_radius):
            ph = warped_phases(int(rng.integers(30, 46)), rng)
            seqs.append(posture(ph, r) + rng.normal(0.0, noise, (len(ph), 6)))
            rs.append(r)
            phases.append(ph)
    return seqs, np.array(rs), phases


CAP_NAMES = ["WRJ2", "WRJ1", "FFJ3", "FFJ4", "MFJ3", "THJ5"]
"""ShadowHand joints standing in for the 6 synthetic dimensions (FFJ3, MFJ3 carry the closure)."""
BALL_JOINTS = ["FF_J2", "MF_J2", "RF_J2", "LF_J2"]


def ball_observations(tau):
    """Ball-swap-like observations (n, 8) at latent phases tau (period π): 4 Gifu joints moving
    twice per ball period, then p1 and p2 opposite each other on a circle (one turn per period)."""
    tau = np.asarray(tau, dtype=float)
    a = 2.0 * tau
    hand = np.c_[
        0.6 + 0.3 * np.sin(2 * a), 0.6 + 0.3 * np.cos(2 * a), 0.6 - 0.3 * np.sin(2 * a), 0.6 - 0.3 * np.cos(2 * a)
    ]
    p1 = 0.5 * np.c_[np.cos(a), np.sin(a)]
    return np.c_[hand, p1, -p1]


def ball_sequences(n_seq=3, n=40, seed=0, noise=0.005):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n_seq):
        tau = np.pi * (np.arange(n) / n + rng.uniform())
        out.append(ball_observations(tau) + rng.normal(0.0, noise, (n, 8)))
    return out
