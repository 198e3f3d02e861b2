"""Rate-over-time figures of the disturbance evaluation (docs/manipulation.md §5).

One PNG per scene (``balls``, ``cap``): a panel per disturbance class, one line per controller
(the first seed's run), the progress rate over the trailing hand cycle in the direction of the
controller's calm run, the calm rate dashed,
and each disturbance marked by a line in its controller's colour (the cap controllers start
turning at different times, so their disturbances fall at different times) with a red band
while it lasts.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from .disturbances import filled, rate_over_time

UNITS = {"progress": "swaps/min", "turns": "deg/min"}


def plot_rates(runs: dict, classes: dict, key: str, folder, scene: str, cycle_s: float) -> Path:
    """Write ``<folder>/<scene>_rates.png`` from the runs ``{seed: {controller: {"calm": run,
    CLASS: (times, run)}}}``; returns its path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    seed = next(iter(runs))
    scale = 360.0 if key == "turns" else 1.0
    fig, axes = plt.subplots(len(classes), 1, figsize=(9, 2.4 * len(classes)), sharex=True, squeeze=False)
    for ax, (cls, spec) in zip(axes[:, 0], classes.items()):
        for i, (name, row) in enumerate(runs[seed].items()):
            times, run = row[cls]
            calm, colour = row["calm"], f"C{i}"
            sign = scale if filled(calm[key])[-1] >= 0 else -scale
            ax.plot(run["times"], sign * rate_over_time(run["times"], run[key], cycle_s), colour, lw=1.2, label=name)
            ax.plot(calm["times"], sign * rate_over_time(calm["times"], calm[key], cycle_s), colour, lw=0.6, ls="--")
            for t in times:
                if spec.duration_s > 0:
                    ax.axvspan(t, t + spec.duration_s, color="red", alpha=0.1)
                ax.axvline(t, color=colour, lw=0.8, ls=":")
        ax.set_title(f"{cls}: {spec.doc}", fontsize=9)
        ax.set_ylabel(UNITS[key])
    axes[0, 0].legend(fontsize=8, loc="lower right")
    axes[-1, 0].set_xlabel(f"simulated time (s); rate over the trailing {cycle_s:g} s, calm runs dashed")
    fig.tight_layout()
    path = folder / f"{scene}_rates.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
