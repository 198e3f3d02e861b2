"""Colour-blob tracker for the health-ball scene (docs/manipulation.md, closed loop step 1).

OpenCV on an RGB image: HSV thresholds → morphological opening → external contours → centroids
from image moments.  Two identical balls and two reference marks near the wrist are found; ball
positions are normalised so that mark A sits at (−1, 0) and mark B at (1, 0)
(:func:`normalise_points`).  A blob that is not seen is reported invalid, never invented; when a
mark is missing no ball can be normalised, so all balls are reported invalid for that frame.

Documented choices:
- two touching balls form one blob; a blob whose minimum-area rectangle is more elongated than
  ``merge_aspect`` is split in two with 2-means on its pixel coordinates (for two equal touching
  discs the cluster centres are the disc centres);
- balls are identical, so they are reported unordered with track ids from nearest-neighbour
  association with the previous frame (the assignment with the smaller summed distance; a track
  lost for longer than ``max_lost`` frames or re-found farther than ``max_jump`` px gets a new id).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import permutations

import cv2
import numpy as np


@dataclass(frozen=True)
class HSVRange:
    """Inclusive OpenCV HSV bounds (H 0–179, S and V 0–255); ``lower[0] > upper[0]`` wraps the hue (reds)."""

    lower: tuple[int, int, int]
    upper: tuple[int, int, int]

    def mask(self, hsv: np.ndarray) -> np.ndarray:
        lo, hi = np.array(self.lower, np.uint8), np.array(self.upper, np.uint8)
        if lo[0] <= hi[0]:
            return cv2.inRange(hsv, lo, hi)
        return cv2.inRange(hsv, lo, np.array([179, hi[1], hi[2]], np.uint8)) | cv2.inRange(
            hsv, np.array([0, lo[1], lo[2]], np.uint8), hi
        )


BALL_HSV = HSVRange((15, 120, 70), (35, 255, 255))
"""Yellow balls of the simulated scene (handflow.plugins.simulator.scenes.BALL_COLOUR)."""
MARK_A_HSV = HSVRange((170, 120, 70), (8, 255, 255))
"""Red mark A → (−1, 0)."""
MARK_B_HSV = HSVRange((45, 120, 50), (85, 255, 255))
"""Green mark B → (1, 0)."""


def blob_centroids(mask: np.ndarray, min_area: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """(centroid (2,), contour) of every external blob of at least ``min_area`` px, largest first."""
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    out = []
    for c in sorted(contours, key=cv2.contourArea, reverse=True):
        m = cv2.moments(c)
        if m["m00"] >= min_area:
            out.append((np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]]), c))
    return out


def normalise_points(points: np.ndarray, mark_a: np.ndarray, mark_b: np.ndarray) -> np.ndarray:
    """Similarity transform of image points (n, 2) taking ``mark_a`` to (−1, 0) and ``mark_b`` to (1, 0)."""
    z = points[:, 0] + 1j * points[:, 1]
    a, b = complex(*mark_a), complex(*mark_b)
    if abs(b - a) < 1e-9:
        raise ValueError("the two reference marks coincide; cannot normalise")
    w = (z - (a + b) / 2) / ((b - a) / 2)
    return np.c_[w.real, w.imag]


@dataclass
class TrackResult:
    """One frame: balls (normalised, validity, track ids) and marks (pixels, validity)."""

    balls: np.ndarray
    balls_valid: np.ndarray
    ids: np.ndarray
    balls_px: np.ndarray
    marks_px: np.ndarray
    marks_valid: np.ndarray


@dataclass
class _Track:
    id: int
    pos: np.ndarray
    lost: int = 0


@dataclass
class BallTracker:
    """Find and track two identical balls and two reference marks in RGB images (see module docstring)."""

    ball_hsv: HSVRange = BALL_HSV
    mark_a_hsv: HSVRange = MARK_A_HSV
    mark_b_hsv: HSVRange = MARK_B_HSV
    min_area: float = 12.0
    merge_aspect: float = 1.5
    max_jump: float = 60.0
    max_lost: int = 30
    n_balls: int = 2
    _tracks: list[_Track] = field(default_factory=list, init=False, repr=False)
    _next_id: int = field(default=0, init=False, repr=False)

    def reset(self) -> None:
        self._tracks, self._next_id = [], 0

    # -- detection -------------------------------------------------------------------------
    def detect_balls(self, hsv: np.ndarray) -> np.ndarray:
        """Pixel centroids (k, 2) of up to ``n_balls`` balls, splitting a merged blob."""
        mask = cv2.morphologyEx(self.ball_hsv.mask(hsv), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
        blobs = blob_centroids(mask, self.min_area)[: self.n_balls]
        if len(blobs) == 1 and self.n_balls == 2:
            (w, h) = cv2.minAreaRect(blobs[0][1])[1]
            if max(w, h) > self.merge_aspect * max(min(w, h), 1.0):
                return self._split(mask, blobs[0][1])
        return np.array([c for c, _ in blobs]).reshape(-1, 2)

    @staticmethod
    def _split(mask: np.ndarray, contour: np.ndarray) -> np.ndarray:
        blob = np.zeros_like(mask)
        cv2.drawContours(blob, [contour], -1, 255, thickness=cv2.FILLED)
        ys, xs = np.nonzero(blob & mask)
        pts = np.c_[xs, ys].astype(np.float32)
        criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.05)
        # deterministic start: the two ends of the blob's principal axis
        centre = pts.mean(axis=0)
        axis = np.linalg.svd(pts - centre, full_matrices=False)[2][0]
        proj = (pts - centre) @ axis
        labels = (proj > 0).astype(np.int32).reshape(-1, 1)
        _, _, centres = cv2.kmeans(pts, 2, labels, criteria, 1, cv2.KMEANS_USE_INITIAL_LABELS)
        return centres.astype(float)

    def detect_mark(self, hsv: np.ndarray, rng: HSVRange) -> np.ndarray | None:
        """Pixel centroid of the largest blob in ``rng`` or None."""
        blobs = blob_centroids(rng.mask(hsv), self.min_area / 4)
        return blobs[0][0] if blobs else None

    # -- tracking ---------------------------------------------------------------------------
    def _associate(self, detections: np.ndarray) -> list[tuple[_Track, np.ndarray | None]]:
        """Pair tracks with detections: most matches within ``max_jump``, then the smallest summed distance."""
        alive = [t for t in self._tracks if t.lost <= self.max_lost]
        n = len(detections)
        if len(alive) >= n:
            candidates = [dict(zip(perm, range(n))) for perm in permutations(range(len(alive)), n)]
        else:
            candidates = [dict(enumerate(perm)) for perm in permutations(range(n), len(alive))]
        best: dict[int, int] = {}
        best_key = (0, 0.0)
        for cand in candidates:
            dist = {i: float(np.linalg.norm(alive[i].pos - detections[j])) for i, j in cand.items()}
            match = {i: j for i, j in cand.items() if dist[i] <= self.max_jump}
            key = (-len(match), sum(dist[i] for i in match))
            if not best or key < best_key:
                best, best_key = match, key
        pairs: list[tuple[_Track, np.ndarray | None]] = [
            (t, detections[best[i]] if i in best else None) for i, t in enumerate(alive)
        ]
        for j in sorted(set(range(n)) - set(best.values())):
            pairs.append((_Track(self._next_id, detections[j]), detections[j]))
            self._next_id += 1
        return pairs

    def update(self, rgb: np.ndarray) -> TrackResult:
        """Process one RGB image (h, w, 3) uint8 and return the frame's :class:`TrackResult`."""
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ValueError(f"tracker needs an RGB uint8 image (h, w, 3), got {rgb.dtype} {rgb.shape}")
        hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
        detections = self.detect_balls(hsv)
        pairs = self._associate(detections)
        kept: list[_Track] = []
        for track, det in pairs:
            if det is None:
                track.lost += 1
            else:
                track.pos, track.lost = det, 0
            kept.append(track)
        # keep the n_balls most recently seen tracks, reported in id order
        kept = sorted(sorted(kept, key=lambda t: (t.lost, t.id))[: self.n_balls], key=lambda t: t.id)
        self._tracks = kept
        ids = np.array([t.id for t in kept] + [-1] * (self.n_balls - len(kept)), dtype=np.int64)
        seen = np.array([t.lost == 0 for t in kept] + [False] * (self.n_balls - len(kept)))
        px = np.full((self.n_balls, 2), np.nan)
        px[seen] = np.array([t.pos for t in kept if t.lost == 0]).reshape(-1, 2)
        marks = [self.detect_mark(hsv, self.mark_a_hsv), self.detect_mark(hsv, self.mark_b_hsv)]
        marks_valid = np.array([m is not None for m in marks])
        marks_px = np.array([m if m is not None else [np.nan, np.nan] for m in marks], dtype=float)
        balls = np.full((self.n_balls, 2), np.nan)
        valid = seen & marks_valid.all()
        if valid.any():
            balls[valid] = normalise_points(px[valid], marks_px[0], marks_px[1])
        return TrackResult(balls, valid, ids, px, marks_px, marks_valid)
