"""Pinhole camera of a scene: TinyRenderer images and the projection of world points into them.

Both use the same OpenGL view/projection matrices, so a projected ground-truth point lands where
pybullet draws it (used to measure the tracker's error, docs/simulator.md closed loop).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bullet import pybullet as p


@dataclass(frozen=True)
class CameraSpec:
    """Eye and target in world coordinates (m), image-up vector, vertical field of view (deg), clip planes."""

    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float]
    fov_deg: float = 50.0
    near: float = 0.02
    far: float = 2.0

    def matrices(self, width: int, height: int) -> tuple[list[float], list[float]]:
        """(view, projection) matrices as pybullet wants them (column-major flat lists)."""
        view = p.computeViewMatrix(self.eye, self.target, self.up)
        proj = p.computeProjectionMatrixFOV(self.fov_deg, width / height, self.near, self.far)
        return view, proj

    def render(self, client: int, width: int, height: int) -> np.ndarray:
        """An RGB image (height, width, 3) uint8 from the TinyRenderer (headless, deterministic)."""
        if width < 8 or height < 8:
            raise ValueError(f"camera image must be at least 8×8 pixels, got {width}×{height}")
        view, proj = self.matrices(width, height)
        _, _, rgba, _, _ = p.getCameraImage(
            width, height, view, proj, renderer=p.ER_TINY_RENDERER, shadow=0, physicsClientId=client
        )
        return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy()

    def project(self, points: np.ndarray, width: int, height: int) -> np.ndarray:
        """Pixel coordinates (u right, v down; pixel centres at .5) of world points (n, 3) → (n, 2)."""
        view, proj = self.matrices(width, height)
        m = np.asarray(proj).reshape(4, 4).T @ np.asarray(view).reshape(4, 4).T
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        clip = np.c_[pts, np.ones(len(pts))] @ m.T
        ndc = clip[:, :2] / clip[:, 3:4]
        return np.c_[(ndc[:, 0] + 1) * 0.5 * width, (1 - ndc[:, 1]) * 0.5 * height]
