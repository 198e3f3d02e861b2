"""Figures like the thesis' (chapter 6): trajectories coloured by assigned label, compatibility
curves over time, and a summary of the evaluation.  Matplotlib with the Agg backend only."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def _colours(n: int):
    cmap = plt.get_cmap("tab20" if n > 10 else "tab10")
    return [cmap(k % cmap.N) for k in range(n)]


def plot_labelled_trajectory(
    Y: np.ndarray,
    labels: np.ndarray,
    classes: list[str],
    path: str | Path,
    title: str = "",
    truth: np.ndarray | None = None,
) -> Path:
    """First two dimensions of Y, each point coloured by its label; rejected points as black crosses."""
    Y = np.asarray(Y, dtype=float)
    fig, ax = plt.subplots(figsize=(5, 4.5))
    yy = Y[:, 1] if Y.shape[1] > 1 else np.arange(len(Y))  # 1D data: plotted against the index
    ax.plot(Y[:, 0], yy, color="0.8", lw=1, zorder=0)
    cols = _colours(len(classes))
    for k, c in enumerate(classes):
        sel = labels == k
        if sel.any():
            ax.scatter(Y[sel, 0], yy[sel], s=14, color=cols[k], label=c)
    rej = labels < 0
    if rej.any():
        ax.scatter(Y[rej, 0], yy[rej], s=18, marker="x", color="k", label="rejected")
    if truth is not None:
        title = f"{title}  ({100 * np.mean(labels == truth):.0f} % correct)"
    ax.set_title(title, fontsize=9)
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7, loc="best")
    return _save(fig, path)


def plot_compatibilities(
    C: np.ndarray, classes: list[str], path: str | Path, title: str = "", ylabel: str = "compatibility C(t)"
) -> Path:
    """One curve per candidate over the observation index."""
    fig, ax = plt.subplots(figsize=(6, 3))
    for k, (c, col) in enumerate(zip(classes, _colours(len(classes)))):
        ax.plot(C[:, k], color=col, lw=1.2, label=c)
    ax.set_xlabel("observation")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, ncol=4)
    return _save(fig, path)


def plot_summary(result: dict, path: str | Path) -> Path:
    """Bar chart: share of cases ≥ 85 % correct per method and experiment."""
    methods = list(result["methods"])
    experiments = list(next(iter(result["methods"].values())))
    fig, ax = plt.subplots(figsize=(8, 3.5))
    width = 0.8 / max(len(methods), 1)
    for k, m in enumerate(methods):
        vals = [result["methods"][m][e]["share_ge_85"] or 0.0 for e in experiments]
        ax.bar(np.arange(len(experiments)) + k * width, vals, width, label=m)
    ax.set_xticks(np.arange(len(experiments)) + 0.4 - width / 2, experiments, fontsize=8)
    ax.set_ylabel("share of cases ≥ 85 % correct")
    ax.set_ylim(0, 1)
    ax.legend(fontsize=8)
    return _save(fig, path)


def _save(fig, path: str | Path) -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def plot_label_ribbons(
    truth: np.ndarray, labels: dict[str, np.ndarray], classes: list[str], path: str | Path, title: str = ""
) -> Path:
    """One ribbon per row: the true labels, then every method's labels over time (rejected = black)."""
    colours = np.array([*_colours(len(classes)), (0, 0, 0, 1), (1, 1, 1, 1)])  # …, rejected, unlabelled
    rows = [("truth", truth), *labels.items()]
    img = np.stack(
        [np.where(r == -1, len(classes), r) if n != "truth" else np.where(r < 0, len(classes) + 1, r) for n, r in rows]
    )
    fig, ax = plt.subplots(figsize=(10, 0.45 * len(rows) + 1.2))
    ax.imshow(colours[img], aspect="auto", interpolation="nearest")
    ax.set_yticks(range(len(rows)), [n for n, _ in rows])
    ax.set_xlabel("frame")
    handles = [plt.Rectangle((0, 0), 1, 1, color=colours[k]) for k in range(len(classes) + 1)]
    ax.legend(
        handles,
        [*classes, "rejected"],
        ncol=min(8, len(classes) + 1),
        fontsize=7,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.25 if len(rows) > 3 else -0.5),
    )
    ax.set_title(title)
    return _save(fig, path)


def plot_confusion(truth: np.ndarray, pred: np.ndarray, classes: list[str], path: str | Path, title: str = "") -> Path:
    """Row-normalised confusion matrix of the labelled frames; the last column counts rejections."""
    keep = truth >= 0
    n = len(classes)
    M = np.zeros((n, n + 1))
    np.add.at(M, (truth[keep], np.where(pred[keep] < 0, n, pred[keep])), 1)
    M /= np.maximum(M.sum(axis=1, keepdims=True), 1)
    fig, ax = plt.subplots(figsize=(0.5 * n + 3, 0.45 * n + 2))
    ax.imshow(M, cmap="Blues", vmin=0, vmax=1)
    ax.set_xticks(range(n + 1), [*classes, "rej."], rotation=60, fontsize=7)
    ax.set_yticks(range(n), classes, fontsize=7)
    for (i, j), v in np.ndenumerate(M):
        if v >= 0.01:
            ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=6, color="white" if v > 0.5 else "black")
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    ax.set_title(title)
    return _save(fig, path)


def plot_tradeoff(curves: dict[str, dict], path: str | Path, title: str = "") -> Path:
    """Known-class accuracy against unknown rejection as each method's rejection parameter varies."""
    fig, ax = plt.subplots(figsize=(5, 4.5))
    for name, c in curves.items():
        ax.plot(c["unknown_rejection"], c["known_accuracy"], marker=".", label=f"{name} (area {c['auc']:.2f})")
    ax.set_xlabel("unknown rejection")
    ax.set_ylabel("known accuracy")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.legend(fontsize=7)
    ax.set_title(title)
    return _save(fig, path)
