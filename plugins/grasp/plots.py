"""Pictures of a SOM grasp manifold (thesis Fig. 4.3, 4.4): inter-node distances and node postures.

- :func:`plot_u_matrix`: the lattice with every neighbour connection shaded by the distance of the two
  reference postures (black = largest, light grey = smallest) and the nodes that win training data
  (``hits``) marked green — cluster borders show up as dark lines;
- :func:`plot_node_postures`: a contiguous ``extract × extract`` block of nodes, each rendered as the
  simulated hand in that posture (pybullet TinyRenderer), framed in a colour for the node's mean
  distance to its neighbours (red: smallest, green: medium, blue: largest).
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.colors import LinearSegmentedColormap

from handflow.plugins.simulator.camera import CameraSpec
from handflow.plugins.simulator.simulation import Simulation

from ..simulator.bullet import pybullet as p
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
