"""Experience bases and grasp datasets (docs/grasping.md, thesis 4.1–4.2).

An experience base is a set of postures over named joints with one query, the PCP best match.
Three sources share that interface (:class:`ExperienceBase`):

- ``som``: the reference postures of a SOM grasp manifold (:mod:`.som`);
- ``database``: the raw postures of successful grasps (a :class:`GraspDataset`);
- ``manifold``: any array of postures, e.g. sampled from a manipulation manifold (the cap-turning
  controller's grasp initialisation, docs/grasping.md).

:class:`GraspDataset` is the on-disk form of generated experience: one ``.npz`` with the postures,
object type and pose of every successful grasp plus a JSON metadata string (touching segments per
grasp, generation settings); read without pickle.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from handflow.framework.files.npz import NpzFileError, building, npz_metadata, read_npz

from .pcp import best_match_index, pcp_distances
from .som import SOM, load_som

DATASET_FORMAT = "handflow.grasp_dataset"
DATASET_VERSION = 1
EXPERIENCE_HINT = "create it with `handflow grasp-experience` or `handflow grasp-som` (docs/grasping.md)"
POSE_FIELDS = ("x", "y", "gap", "yaw_deg")
"""Object pose columns: offset along the fingers and across the palm (m), gap below the palm (m), yaw (deg)."""


@dataclass
class ExperienceBase:
    """Postures (M, d) over joint ``names``; ``best_match`` = argmin of the PCP distance."""

    postures: np.ndarray
    names: tuple[str, ...]
    kind: str = "manifold"

    def __post_init__(self) -> None:
        self.postures = np.atleast_2d(np.asarray(self.postures, dtype=float))
        self.names = tuple(self.names)
        if self.postures.shape[1] != len(self.names) or len(self.postures) == 0:
            raise ValueError(
                f"experience base needs (M ≥ 1, {len(self.names)}) postures for joints "
                f"{list(self.names)}, got shape {self.postures.shape}"
            )
        if not np.isfinite(self.postures).all():
            raise ValueError("experience postures contain NaN or inf")

    def __len__(self) -> int:
        return len(self.postures)

    def distances(self, theta, mask=None) -> np.ndarray:
        return pcp_distances(self.postures, theta, mask)

    def best_match(self, theta, mask=None) -> tuple[int, np.ndarray]:
        """(index, posture) of the best match of ``theta`` (d,) under the PCP selection ``mask``."""
        k = best_match_index(self.postures, theta, mask)
        return k, self.postures[k]

    @classmethod
    def from_som(cls, som: SOM, names) -> ExperienceBase:
        return cls(som.postures.copy(), tuple(names), "som")

    @classmethod
    def from_dataset(cls, data: GraspDataset) -> ExperienceBase:
        return cls(data.postures.copy(), data.names, "database")

    @classmethod
    def load(cls, path) -> ExperienceBase:
        """From a SOM file (``grasp-som``) or a grasp dataset (``grasp-experience``), told apart by format."""
        path = Path(path)
        if not path.exists():
            raise FileNotFoundError(f"experience file {path} does not exist; {EXPERIENCE_HINT}")
        arrays = read_npz(path, "grasp experience", EXPERIENCE_HINT, names=("metadata",))
        meta = npz_metadata(arrays, path, "grasp experience", EXPERIENCE_HINT)
        if meta.get("format") == DATASET_FORMAT:
            return cls.from_dataset(GraspDataset.load(path))
        som, meta = load_som(path)
        if not isinstance(meta.get("names"), list) or len(meta["names"]) != som.n_features_in_:
            raise NpzFileError(
                f"{path}: SOM file without one joint name per dimension; save it with metadata={{'names': [...]}}"
            )
        return cls.from_som(som, meta["names"])


@dataclass
class GraspDataset:
    """Successful grasps: postures (N, d) over ``names``, object per grasp, pose (N, 4), contacts."""

    names: tuple[str, ...]
    postures: np.ndarray
    objects: np.ndarray
    poses: np.ndarray
    contacts: list[list[str]]
    quality: np.ndarray
    metadata: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.names = tuple(self.names)
        self.postures = np.asarray(self.postures, dtype=float).reshape(-1, len(self.names))
        n = len(self.postures)
        self.objects = np.asarray(self.objects, dtype=str).reshape(n)
        self.poses = np.asarray(self.poses, dtype=float).reshape(n, len(POSE_FIELDS))
        self.quality = np.asarray(self.quality, dtype=float).reshape(n)
        if len(self.contacts) != n:
            raise ValueError(f"{len(self.contacts)} contact lists for {n} grasps")

    def __len__(self) -> int:
        return len(self.postures)

    def select(self, obj: str | None) -> GraspDataset:
        """The grasps of one object (``None``: all)."""
        keep = np.ones(len(self), bool) if obj is None else self.objects == obj
        return GraspDataset(
            self.names,
            self.postures[keep],
            self.objects[keep],
            self.poses[keep],
            [c for c, k in zip(self.contacts, keep) if k],
            self.quality[keep],
            dict(self.metadata),
        )

    @classmethod
    def concatenate(cls, parts: list[GraspDataset]) -> GraspDataset:
        if not parts:
            raise ValueError("no grasp datasets to concatenate")
        names = parts[0].names
        if any(p.names != names for p in parts):
            raise ValueError("grasp datasets disagree on the joint names; they come from different hands")
        return cls(
            names,
            np.vstack([p.postures for p in parts]),
            np.concatenate([p.objects for p in parts]),
            np.vstack([p.poses for p in parts]),
            [c for p in parts for c in p.contacts],
            np.concatenate([p.quality for p in parts]),
            dict(parts[0].metadata),
        )

    def save(self, path) -> None:
        meta = {
            "format": DATASET_FORMAT,
            "format_version": DATASET_VERSION,
            "names": list(self.names),
            "pose_fields": list(POSE_FIELDS),
            "contacts": self.contacts,
            **self.metadata,
        }
        with open(path, "wb") as fh:
            np.savez(
                fh,
                postures=self.postures,
                objects=self.objects,
                poses=self.poses,
                quality=self.quality,
                metadata=np.array(json.dumps(meta)),
            )

    @classmethod
    def load(cls, path) -> GraspDataset:
        """Read a dataset written by :meth:`save`; a bad file raises
        :class:`~handflow.framework.files.npz.NpzFileError` (a ``ValueError``) naming it."""
        what, hint = "grasp dataset", "regenerate it with `handflow grasp-experience` (docs/grasping.md)"
        arrays = read_npz(path, what, hint)
        meta = npz_metadata(arrays, path, what, hint, fmt=(DATASET_FORMAT, DATASET_VERSION, "format_version"))
        with building(path, what, hint):
            names = meta.pop("names")
            contacts = meta.pop("contacts")
            for k in ("format", "format_version", "pose_fields"):
                meta.pop(k, None)
            return cls(names, arrays["postures"], arrays["objects"], arrays["poses"], contacts, arrays["quality"], meta)
