"""A manipulation manifold on disk: a Structured UKR model plus what the controllers need to
drive a hand with it (docs/manipulation.md): the name of every observation dimension, the
hand model, the latent dimension names and how the manifold was made.

Stored inside the UKR model file's provenance under the key ``manipulation`` (no second file,
nothing executable).  Observation names are joint names of the hand model and, for the
ball-swapping manifold, :data:`BALL_NAMES`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from handflow.framework.files.npz import building
from handflow.plugins.hands.joints import HAND_MODELS
from handflow.plugins.manifold.model import StructuredUKR
from handflow.plugins.manifold.validation import InvalidInputError, parse_latent

BALL_NAMES = ("p1_x", "p1_y", "p2_x", "p2_y")
"""Observation names of the two normalised ball positions (p1, p2) of the ball-swap manifold."""


@dataclass
class ManipulationManifold:
    """``model`` with named observation dimensions; ``kind`` is constructed | learned | ball_swap."""

    model: StructuredUKR
    names: list[str]
    hand: str
    latent_names: list[str]
    kind: str

    def __post_init__(self) -> None:
        if self.hand not in HAND_MODELS:
            raise InvalidInputError(f"unknown hand {self.hand!r}; use one of {', '.join(HAND_MODELS)}")
        if len(self.names) != self.model.n_features_in_:
            raise InvalidInputError(
                f"{len(self.names)} observation names for a model with {self.model.n_features_in_} dimensions"
            )
        hand_joints = set(HAND_MODELS[self.hand].names)
        unknown = [n for n in self.names if n not in hand_joints and n not in BALL_NAMES]
        if unknown:
            raise InvalidInputError(
                f"observation names {unknown} are neither joints of hand "
                f"'{self.hand}' nor ball coordinates {BALL_NAMES}"
            )
        self.joint_index = np.array([i for i, n in enumerate(self.names) if n in hand_joints])
        self.joint_names = [self.names[i] for i in self.joint_index]
        self.ball_index = np.array([self.names.index(n) for n in BALL_NAMES if n in self.names])
        if self.ball_index.size not in (0, 4):
            raise InvalidInputError(f"a ball manifold needs all of {BALL_NAMES}")
        self.periodic_dims = parse_latent(self.model.latent)[0].periodic

    # -- latent layout ---------------------------------------------------------------------------
    @property
    def q(self) -> int:
        return self.model.latents_.shape[1]

    @property
    def time_dim(self) -> int:
        if self.model.time_dim_ is None:
            raise InvalidInputError("the manifold has no time dimension; controllers need one")
        return int(self.model.time_dim_)

    @property
    def periodic(self) -> bool:
        """Whether the time axis wraps (period π) — learned manifolds; constructed ones reset."""
        return bool(self.periodic_dims[self.time_dim])

    @property
    def time_sign(self) -> float:
        """+1 or −1: the direction of latent time along the demonstrations (a learned time axis
        may run backwards); controllers advance their time by ``time_sign · delta``."""
        t = self.model.latents_[:, self.time_dim]
        ids = self.model.sequence_ids_
        d = np.diff(t)[ids[1:] == ids[:-1]]
        if self.periodic:
            d = np.mod(d + np.pi / 2, np.pi) - np.pi / 2
        return 1.0 if d.sum() >= 0 else -1.0

    def range(self, dim: int) -> tuple[float, float]:
        """Latent interval of dimension ``dim``: ``[0, π)`` if periodic, else the training span."""
        if self.periodic_dims[dim]:
            return 0.0, float(np.pi)
        col = self.model.latents_[:, dim]
        return float(col.min()), float(col.max())

    # -- mappings --------------------------------------------------------------------------------
    def observation(self, X, extrapolate: bool = False, span: float = 0.25) -> np.ndarray:
        """f(x) for latents (M, q) or (q,).

        ``extrapolate``: beyond the training span of a non-periodic dimension, continue f
        linearly with the secant slope over the last ``span`` (fraction of the span) inside the
        border (documented choice: kernel regression flattens out at the border, so its own
        derivative there would not extend the trend; 0.25 = one radius spacing on the constructed
        cap manifold).  Without it, f saturates at the border value."""
        X = np.asarray(X, dtype=float)
        Y = self.model.inverse_transform(X)
        if not extrapolate:
            return Y
        X2 = np.atleast_2d(X)
        Y2 = np.atleast_2d(Y).copy()
        for dim in range(self.q):
            if self.periodic_dims[dim]:
                continue
            lo, hi = self.range(dim)
            h = span * (hi - lo)
            for border, inward in ((lo, h), (hi, -h)):
                out = (X2[:, dim] - border) * np.sign(inward) < 0
                if not out.any():
                    continue
                at, near = X2[out].copy(), X2[out].copy()
                at[:, dim], near[:, dim] = border, border + inward
                f_at = np.atleast_2d(self.model.inverse_transform(at))
                slope = (f_at - np.atleast_2d(self.model.inverse_transform(near))) / -inward
                Y2[out] = f_at + slope * (X2[out, dim] - border)[:, None]
        return Y2.reshape(Y.shape)

    def posture(self, X, extrapolate: bool = False) -> np.ndarray:
        """Joint part of f(x): (M, n_joints) or (n_joints,) (``extrapolate``: see :meth:`observation`)."""
        return self.observation(X, extrapolate)[..., self.joint_index]

    def project_posture(self, joints: dict[str, float]) -> np.ndarray:
        """Latent of a (partial) hand posture given by joint name (masked projection, §7)."""
        y = np.zeros(len(self.names))
        mask = np.zeros(len(self.names))
        for name, value in joints.items():
            if name in self.names:
                y[self.names.index(name)] = value
                mask[self.names.index(name)] = 1.0
        if not mask.any():
            raise InvalidInputError(
                f"none of the posture's joints {sorted(joints)} is a "
                f"dimension of this manifold ({', '.join(self.joint_names)})"
            )
        return self.model.transform(y, mask)

    # -- persistence -----------------------------------------------------------------------------
    def save(self, path, provenance: dict | None = None) -> None:
        meta = {
            "names": list(self.names),
            "hand": self.hand,
            "latent_names": list(self.latent_names),
            "kind": self.kind,
        }
        self.model.save(path, provenance={**(provenance or {}), "manipulation": meta})

    @classmethod
    def load(cls, path) -> ManipulationManifold:
        """Read a manifold written by :meth:`save`; a plain UKR file gets a clear error."""
        path = Path(path)
        if not path.is_file():
            raise InvalidInputError(f"manifold file {path} not found; train it first (see docs/manipulation.md)")
        try:
            model = StructuredUKR.load(path)
        except ValueError as exc:
            raise InvalidInputError(str(exc)) from None
        hint = "build it with `handflow train configs/train/cap_*.yaml` (docs/manipulation.md)"
        meta = model.provenance_.get("manipulation")
        if not isinstance(meta, dict):
            raise InvalidInputError(
                f"{path} is a UKR model without manipulation metadata (observation names, hand); {hint}"
            )
        with building(path, "manipulation manifold", hint, InvalidInputError):
            return cls(model, list(meta["names"]), meta["hand"], list(meta["latent_names"]), meta["kind"])
