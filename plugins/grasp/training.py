"""Training the SOM grasp manifolds from a grasp dataset (docs/grasping.md, thesis 4.2.2).

Object-specific SOMs (thesis: 25×25) get the grasps of one object, the shared SOM (thesis: 30×30)
those of all objects; each file carries the joint names and the object in its metadata, so
:meth:`~.experience.ExperienceBase.load` can use it as an experience base.
"""

from __future__ import annotations

from pathlib import Path

from .experience import GraspDataset
from .som import SOM, save_som


def train_grasp_som(
    data: GraspDataset,
    obj: str | None,
    rows: int = 25,
    cols: int = 25,
    epochs: int = 300,
    random_state: int | None = 0,
    **som_params,
) -> SOM:
    """A SOM on the postures of ``obj`` (``None``: all objects) of ``data``."""
    part = data.select(obj)
    if len(part) == 0:
        raise ValueError(f"the dataset has no stable grasps of '{obj}'; generate more trials for it")
    return SOM(rows=rows, cols=cols, epochs=epochs, random_state=random_state, **som_params).fit(part.postures)


def train_experience_soms(
    data: GraspDataset,
    folder,
    objects,
    rows: int = 25,
    shared_rows: int = 30,
    epochs: int = 300,
    random_state: int | None = 0,
    progress=None,
) -> list[Path]:
    """Write ``som_<object>.npz`` per object and ``som_shared.npz`` into ``folder``; returns the paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for obj, size in [(o, rows) for o in objects] + [(None, shared_rows)]:
        som = train_grasp_som(data, obj, size, size, epochs, random_state)
        part = data.select(obj)
        path = folder / f"som_{obj or 'shared'}.npz"
        save_som(
            som,
            path,
            {
                "names": list(data.names),
                "object": obj or "all",
                "n_postures": len(part),
                "quantization_error": som.quantization_error(part.postures),
                "topographic_error": som.topographic_error(part.postures),
            },
        )
        written.append(path)
        if progress is not None:
            progress(f"trained {path.name}: {size}×{size} nodes on {len(part)} grasps")
    return written
