"""Pictures of a SOM grasp manifold (thesis Fig. 4.3, 4.4): inter-node distances and node postures.

- :func:`plot_u_matrix`: the lattice with every neighbour connection shaded by the distance of the two
  reference postures (black = largest, light grey = smallest) and the nodes that win training data
  (``hits``) marked green — cluster borders show up as dark lines;
- :func:`plot_node_postures`: a contiguous ``extract × extract`` block of nodes, each rendered as the
  simulated hand in that posture (pybullet TinyRenderer), framed in a colour for the node's mean
  distance to its neighbours (red: smallest, green: medium, blue: largest);
- :func:`plot_success_maps`: grasp success maps of an evaluation — per object the share of stable
  grasps at every grid pose for each condition, and the share per object and condition over seeds.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.colors import LinearSegmentedColormap

from handflow.plugins.simulator.camera import CameraSpec
from handflow.plugins.simulator.simulation import Simulation

from ..simulator.bullet import pybullet as p
from .grid import GraspGrid
from .som import SOM

POSTURE_CAMERA = CameraSpec(eye=(0.19, -0.17, 0.2), target=(0.08, 0.0, 0.27), up=(0.0, 0.0, 1.0), fov_deg=40.0)
"""Camera of the node pictures: in front of and below the palm-down hand, seeing thumb and fingertips."""


DISTANCE_COLOURS = LinearSegmentedColormap.from_list("node_distance", ["red", "green", "blue"])
"""Frame colours of the node pictures: red smallest, green medium, blue largest distance (thesis Fig. 4.3)."""


def plot_u_matrix(som: SOM, path, hits=None, title: str = "SOM grasp manifold") -> None:
    """Write the inter-node distance picture of ``som`` to ``path`` (PNG)."""
    h, v = som.neighbour_distances()
    rows, cols = som.nodes_.shape[:2]
    segs, vals = [], []
    for r in range(rows):
        for c in range(cols - 1):
            segs.append([(c, r), (c + 1, r)])
            vals.append(h[r, c])
    for r in range(rows - 1):
        for c in range(cols):
            segs.append([(c, r), (c, r + 1)])
            vals.append(v[r, c])
    fig, ax = plt.subplots(figsize=(6, 6))
    if hits is not None:
        rr, cc = np.nonzero(np.asarray(hits) > 0)
        ax.scatter(cc, rr, s=60, marker="s", color="#7fd17f", label="supported by data", zorder=1)
    lines = LineCollection(segs, array=np.asarray(vals), cmap="gray_r", linewidths=2.5, zorder=2)
    ax.add_collection(lines)
    fig.colorbar(lines, ax=ax, shrink=0.8, label="distance of neighbouring reference postures (rad)")
    ax.set_xlim(-1, cols)
    ax.set_ylim(rows, -1)
    ax.set_aspect("equal")
    ax.set_title(title)
    if hits is not None:
        ax.legend(loc="upper right", fontsize=8)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)


def render_postures(
    postures: np.ndarray, names, hand: str = "shadow", width: int = 160, height: int = 120
) -> list[np.ndarray]:
    """RGB images of the simulated hand set (without physics) to each posture over joint ``names``."""
    images = []
    with Simulation(hand=hand, scene="empty") as sim:
        cols = [sim.index[n] for n in names]
        for posture in np.atleast_2d(postures):
            q = sim.joint_positions()
            q[cols] = posture
            q = sim.model.clip(q)
            for jid, value in zip(sim.joint_ids, q):
                p.resetJointState(sim.hand_id, int(jid), float(value), physicsClientId=sim.client)
            images.append(POSTURE_CAMERA.render(sim.client, width, height))
    return images


def plot_node_postures(
    som: SOM, names, path, extract: int = 10, hand: str = "shadow", tile: tuple[int, int] = (160, 120), border: int = 4
) -> None:
    """Write a grid of rendered node postures (top-left ``extract × extract`` block) to ``path`` (PNG)."""
    rows, cols = (min(extract, n) for n in som.nodes_.shape[:2])
    block = som.nodes_[:rows, :cols].reshape(rows * cols, -1)
    images = render_postures(block, names, hand, *tile)
    u = som.u_matrix()[:rows, :cols].ravel()
    span = np.ptp(u) or 1.0
    colours = DISTANCE_COLOURS((u - u.min()) / span)[:, :3]
    w, h = tile
    canvas = np.full((rows * (h + 2 * border), cols * (w + 2 * border), 3), 255, np.uint8)
    for k, (img, colour) in enumerate(zip(images, colours)):
        r, c = divmod(k, cols)
        y0, x0 = r * (h + 2 * border), c * (w + 2 * border)
        canvas[y0 : y0 + h + 2 * border, x0 : x0 + w + 2 * border] = (colour * 255).astype(np.uint8)
        canvas[y0 + border : y0 + border + h, x0 + border : x0 + border + w] = img
    plt.imsave(path, canvas)


def success_table(outcomes: list[dict], grid: GraspGrid, obj: str, cond: str) -> tuple[np.ndarray, list, list]:
    """Share of stable grasps of ``cond`` per grid pose of ``obj`` as a (gap, yaw) × (x, y) table (NaN: no valid
    trial), with the row and column labels."""
    v = grid.poses[obj]
    rows, cols = list(itertools.product(v["gap"], v["yaw_deg"])), list(itertools.product(v["x"], v["y"]))
    hits, n = np.zeros((len(rows), len(cols))), np.zeros((len(rows), len(cols)))
    for o in outcomes:
        if o["object"] == obj and o[cond] is not None:
            x, y, gap, yaw = o["pose"]
            r, c = rows.index((gap, yaw)), cols.index((x, y))
            hits[r, c] += o[cond][0]
            n[r, c] += 1
    with np.errstate(invalid="ignore"):
        return hits / np.where(n > 0, n, np.nan), rows, cols


def plot_success_maps(outcomes: list[dict], grid: GraspGrid, folder) -> list[Path]:
    """Write ``success_<object>.png`` (share of stable grasps per grid pose, one panel per condition; grey:
    the pre-grasp already touches the object) and ``success_conditions.png`` (share per object and
    condition, bars = pooled, whiskers = range over seeds) into ``folder``; returns the paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    objects = [o for o in grid.objects if any(r["object"] == o for r in outcomes)]
    conditions = [c for c in ("experience", "no_experience", "shared_som") if c in outcomes[0]]
    cmap = plt.get_cmap("RdYlGn").with_extremes(bad="#bbbbbb")
    paths = []
    for obj in objects:
        fig, axes = plt.subplots(1, len(conditions), figsize=(4.2 * len(conditions), 3.6), squeeze=False)
        for ax, cond in zip(axes[0], conditions):
            table, rows, cols = success_table(outcomes, grid, obj, cond)
            image = ax.imshow(np.ma.masked_invalid(table), cmap=cmap, vmin=0.0, vmax=1.0, aspect="auto")
            ax.set_xticks(range(len(cols)), [f"{100 * x:.1f},{100 * y:+.1f}" for x, y in cols], rotation=90, fontsize=7)
            labels = [f"{100 * g:.1f} cm, {yaw:+.0f}°" for g, yaw in rows] if cond == conditions[0] else []
            ax.set_yticks(range(len(rows)), labels, fontsize=7)
            ax.set_xlabel("x, y (cm)")
            valid = np.isfinite(table)
            share = float(np.nanmean(table)) if valid.any() else 0.0
            ax.set_title(f"{cond}: {share:.0%} of poses", fontsize=9)
        axes[0][0].set_ylabel("gap, yaw")
        fig.colorbar(image, ax=axes[0].tolist(), shrink=0.8, label="share of stable grasps over seeds")
        fig.suptitle(f"{obj} ({grid.name} grid, friction {grid.lateral_friction:g})")
        paths.append(folder / f"success_{obj}.png")
        fig.savefig(paths[-1], dpi=110, bbox_inches="tight")
        plt.close(fig)
    seeds = sorted({o["seed"] for o in outcomes})
    fig, ax = plt.subplots(figsize=(1.6 * len(objects) + 2, 3.6))
    width = 0.8 / len(conditions)
    for j, cond in enumerate(conditions):
        pooled, low, high = [], [], []
        for obj in objects:
            per_seed = [
                [o[cond][0] for o in outcomes if o["object"] == obj and o["seed"] == s and o[cond] is not None]
                for s in seeds
            ]
            shares = [np.mean(v) for v in per_seed if v]
            pooled.append(np.mean(np.concatenate([v for v in per_seed if v])) if shares else 0.0)
            low.append(pooled[-1] - min(shares, default=0.0))
            high.append(max(shares, default=0.0) - pooled[-1])
        x = np.arange(len(objects)) + (j - (len(conditions) - 1) / 2) * width
        ax.bar(x, pooled, width, yerr=[low, high], capsize=3, label=cond)
    ax.set_xticks(range(len(objects)), objects)
    ax.set_ylim(0, 1)
    ax.set_ylabel("share of stable grasps")
    ax.set_title(f"{grid.name} grid, {len(seeds)} seed(s): pooled, range over seeds")
    ax.legend(fontsize=8)
    paths.append(folder / "success_conditions.png")
    fig.savefig(paths[-1], dpi=110, bbox_inches="tight")
    plt.close(fig)
    return paths
