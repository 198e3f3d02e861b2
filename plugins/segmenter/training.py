"""Train one structured UKR manifold per motion class and save the model set.

Each class gets a :class:`handflow.plugins.manifold.StructuredUKR` with one periodic latent time dimension
trained on that class's training trajectories (λ_cseq = 1, λ_pvar = 0 as for the thesis' 1D
models).  Documented choice for the periodic bandwidth: ``beta="auto"`` scales the thesis'
best value β = 12 at 45 points per cycle (docs/training.md) with the mean training length,
``β = 12 · mean_length / 45``.

Documented choice for the latent initialisation (``init``): ``"equidistant"`` (default) spreads
every training sequence chronologically over the whole period ``[0, π)``, as the thesis does for
its 1D motion manifolds (5.2, "equidistantly distributed … according to the chronological
order").  A letter is an *open* stroke; the Isomap + atan2* init (``"isomap"``) maps it onto a
short arc whose ends are not ordered, and the trained time axis then runs back and forth (on the
4 letters e, g, h, l the UKR/CLM's mean share correct rose from 0.71 to 1.00 on validation+test
with the equidistant init, docs/benchmarks.md).  On the periodic axis the
stroke's end meets its start (one wrap-around per repetition), which the order ratings treat as
a forward step.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .candidates import INDEX_FILE, CandidateSet, UKRCandidate
from .cycles import split_cycles
from .datasets import LabelledDataset
from .scaling import ChannelScaling


def auto_beta(sequences: list[np.ndarray]) -> float:
    """``β = 12 · mean_length / 45`` (the thesis' best β at 45 points per cycle, rescaled)."""
    return 12.0 * float(np.mean([len(s) for s in sequences])) / 45.0


INITS = ("equidistant", "isomap")
# ``periodic_quartic`` is compact: class models train on every point through the neighbour-list
# path (docs/training.md, "Training at scale").  Its auto β has the Gaussian's second moment:
# the quartic [1 − β²δ²]₊² has variance 1/(7β²), so β = auto_beta / √7.
KERNELS = ("periodic", "periodic_quartic")
SCALINGS = ("standard", "none")
CYCLES = ("none", "auto")


def train_class_models(dataset: LabelledDataset, **options) -> dict:
    """Fit one StructuredUKR per class of the training split; returns label → fitted model
    (``options`` as for :func:`fit_class_models`)."""
    return fit_class_models(dataset.by_class("train"), **options)


def class_pieces(segments: list[np.ndarray], cycles: str, max_points: int | None) -> tuple[list[np.ndarray], bool]:
    """Training sequences of one class and whether they are cycles of a periodic motion.

    ``cycles="auto"`` cuts every segment into single cycles (:func:`.cycles.split_cycles`;
    segments without repetition stay whole); ``"none"`` keeps the segments.  Documented choice:
    when the pieces hold more than ``max_points`` observations, evenly spaced pieces are kept
    (dense UKR training is quadratic in the number of points); ``max_points=None`` keeps all.
    """
    if cycles not in CYCLES:
        raise ValueError(f"cycles must be one of {CYCLES}, got {cycles!r}")
    pieces, periodic = [], False
    for seg in segments:
        parts = split_cycles(seg) if cycles == "auto" else [seg]
        periodic |= len(parts) > 1
        pieces += parts
    total = sum(map(len, pieces))
    if max_points is not None and total > max_points:
        keep = max(1, int(len(pieces) * max_points / total))
        pieces = [pieces[i] for i in np.linspace(0, len(pieces) - 1, keep).round().astype(int)]
    return pieces, periodic


def fit_class_models(
    by_class: dict[str, list[np.ndarray]],
    beta: float | str = "auto",
    lambda_cseq: float = 1.0,
    n_steps: int = 300,
    init: str = "equidistant",
    random_state: int | None = 0,
    progress: Callable[[str], None] | None = None,
    scaling: str = "standard",
    cycles: str = "none",
    max_points: int = 1500,
    kernel: str = "periodic",
) -> dict:
    """One StructuredUKR per class from label → list of (T, d) training segments.

    ``scaling="standard"`` (default) z-scores every channel with the statistics of all training
    observations (:mod:`.scaling`); ``"none"`` trains on the raw channels.  ``cycles`` see
    :func:`class_pieces`.  Each model's provenance records the scaling and ``open_stroke``: True
    when the class was trained on whole segments (one stroke per period), False when on cycles
    of a periodic motion.  ``kernel="periodic_quartic"`` (compact, see :data:`KERNELS`) trains
    on all pieces, ignoring ``max_points``, in time linear in the number of points.
    """
    from handflow.plugins.manifold import StructuredUKR

    if init not in INITS:
        raise ValueError(f"init must be one of {INITS}, got {init!r}")
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
    compact = kernel == "periodic_quartic"
    if scaling not in SCALINGS:
        raise ValueError(f"scaling must be one of {SCALINGS}, got {scaling!r}")
    scaler = ChannelScaling().fit([s for seqs in by_class.values() for s in seqs]) if scaling == "standard" else None
    models = {}
    for label, segments in by_class.items():
        seqs, periodic = class_pieces(segments, cycles, None if compact else max_points)
        if scaler is not None:
            seqs = [scaler.transform(s) for s in seqs]
        b = (auto_beta(seqs) / (np.sqrt(7.0) if compact else 1.0)) if beta == "auto" else float(beta)
        if progress:
            kind = "cycles" if periodic else "sequences"
            progress(f"training '{label}' on {len(seqs)} {kind} ({sum(map(len, seqs))} points, beta={b:.1f})")
        model = StructuredUKR(
            latent=[{"kernel": kernel, "beta": b, "time": True}],
            lambda_cseq=lambda_cseq,
            lambda_pvar=0.0,
            n_steps=n_steps,
            init=init,
            random_state=random_state,
        ).fit(seqs)
        model.provenance_ = dict(
            model.provenance_, **(scaler.to_provenance() if scaler else {}), open_stroke=not periodic
        )
        models[label] = model
    return models


def candidate_set(models: dict) -> CandidateSet:
    """Wrap fitted StructuredUKR models as candidates."""
    return CandidateSet({label: UKRCandidate(m) for label, m in models.items()})


def save_class_models(models: dict, out_dir: str | Path, provenance: dict | None = None) -> Path:
    """Write ``<label>.npz`` per class plus ``classes.json`` (the index read by the recognisers)."""
    out = Path(out_dir).expanduser()
    out.mkdir(parents=True, exist_ok=True)
    index = {}
    for label, model in models.items():
        name = f"{label}.npz"
        model.save(out / name, provenance=dict(provenance or {}, label=label))
        index[label] = name
    (out / INDEX_FILE).write_text(json.dumps({"classes": index, "provenance": provenance or {}}, indent=2))
    return out
