"""Synthetic letter-like trajectories for tests: class templates plus per-sample variation.

A class template is a smooth closed planar (or d-dimensional) curve: a Fourier series in the phase
``φ ∈ [0, 1)`` with class-specific random coefficients whose first harmonic dominates (so every
template is one loop, like a letter written in one stroke).  A sample of a class varies the
template's **timing** (a random monotone phase warp and a random length), **amplitude** (a
per-dimension scale) and adds white **noise**.  Everything derives from ``random_state``.
"""

from __future__ import annotations

import numpy as np

from ._trajectories import LabelledDataset, Trajectory


class LetterGenerator:
    """Seedable generator of class templates and their varied samples.

    Parameters
    ----------
    n_classes : number of templates (labels ``"A"``, ``"B"``, …).
    dim : dimension of the trajectories.
    harmonics : Fourier harmonics per template.
    length : mean number of points per sample; each sample's length varies by ``±length_jitter``.
    warp : strength of the timing warp ``φ = u + w sin(2πu)/π``, ``|w| ≤ warp``; clipped to 0.15
        so the warp stays monotone.
    amplitude_jitter : relative std of the per-dimension amplitude scale.
    noise : std of additive white noise (template amplitude is about 1).
    random_state : seed; the templates come from it, the samples from a derived stream.
    """

    def __init__(
        self,
        n_classes: int = 4,
        dim: int = 2,
        harmonics: int = 3,
        length: int = 80,
        length_jitter: float = 0.15,
        warp: float = 0.1,
        amplitude_jitter: float = 0.05,
        noise: float = 0.01,
        random_state: int | None = None,
    ) -> None:
        if not 1 <= n_classes <= 26:
            raise ValueError(f"n_classes must lie in 1..26, got {n_classes}")
        self.n_classes = n_classes
        self.dim = dim
        self.harmonics = harmonics
        self.length = length
        self.length_jitter = length_jitter
        self.warp = min(warp, 0.15)
        self.amplitude_jitter = amplitude_jitter
        self.noise = noise
        self.random_state = random_state
        rng = np.random.default_rng(random_state)
        scale = 0.6 / np.arange(1, harmonics + 1)
        self.coefficients_ = rng.normal(size=(n_classes, 2, harmonics, dim)) * scale[None, None, :, None]
        # first harmonic: an ellipse traversed counter-clockwise in the first two dimensions, so no
        # class is the reversal of another
        self.coefficients_[:, 0, 0, 0] += 1.0
        self.coefficients_[:, 1, 0, min(1, dim - 1)] += 1.0
        self.labels_ = [chr(ord("A") + i) for i in range(n_classes)]
        self._rng = np.random.default_rng(rng.integers(2**63))

    def template(self, label: str, phase: np.ndarray) -> np.ndarray:
        """Noise-free template of ``label`` at phases ``phase`` (any shape) → (..., dim)."""
        c = self.coefficients_[self.labels_.index(label)]
        k = np.arange(1, self.harmonics + 1)
        ang = 2 * np.pi * np.asarray(phase, dtype=float)[..., None] * k
        return np.cos(ang) @ c[0] + np.sin(ang) @ c[1]

    def sample(self, label: str) -> np.ndarray:
        """One varied sample (T, dim) of class ``label``, one full cycle from phase 0."""
        rng = self._rng
        n = max(8, int(round(self.length * (1 + rng.uniform(-self.length_jitter, self.length_jitter)))))
        u = np.arange(n) / n
        phase = u + self.warp * rng.uniform(-1, 1) * np.sin(2 * np.pi * u) / np.pi  # slope >= 1 - 2·warp
        y = self.template(label, phase) * (1 + self.amplitude_jitter * rng.normal(size=self.dim))
        return y + self.noise * rng.normal(size=y.shape)

    def dataset(self, per_split: tuple[int, int, int] = (5, 5, 5)) -> LabelledDataset:
        """Train / validation / test samples per class (the thesis protocol's 5/5/5 by default)."""
        splits = []
        for name, count in zip(("train", "validation", "test"), per_split):
            splits.append(
                [Trajectory(lab, self.sample(lab), f"{name}/{lab}_{i}") for lab in self.labels_ for i in range(count)]
            )
        return LabelledDataset(*splits, columns=[f"y{i}" for i in range(self.dim)], source="synthetic")
