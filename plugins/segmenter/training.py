"""Train one structured UKR manifold per motion class (issue 7 item 1) and save the model set.

Each class gets a :class:`handflow.plugins.manifold.StructuredUKR` with one periodic latent time dimension
trained on that class's training trajectories (λ_cseq = 1, λ_pvar = 0 as for the thesis' 1D
models).  Documented choice for the periodic bandwidth: ``beta="auto"`` scales the thesis'
best value β = 12 at 45 points per cycle (spec ukr.md §4) with the mean training length,
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
from .datasets import LabelledDataset
from .scaling import ChannelScaling


def auto_beta(sequences: list[np.ndarray]) -> float:
    """``β = 12 · mean_length / 45`` (the thesis' best β at 45 points per cycle, rescaled)."""
    return 12.0 * float(np.mean([len(s) for s in sequences])) / 45.0


INITS = ("equidistant", "isomap")
SCALINGS = ("standard", "none")


def train_class_models(
    dataset: LabelledDataset,
    beta: float | str = "auto",
    lambda_cseq: float = 1.0,
    n_steps: int = 300,
    init: str = "equidistant",
    random_state: int | None = 0,
    progress: Callable[[str], None] | None = None,
    scaling: str = "standard",
) -> dict:
    """Fit one StructuredUKR per class of the training split; returns label → fitted model.

    ``scaling="standard"`` (default) z-scores every channel with the statistics of all training
    observations (:mod:`.scaling`) and stores the scaling in each model's provenance;
    ``"none"`` trains on the raw channels.
    """
    if scaling not in SCALINGS:
        raise ValueError(f"scaling must be one of {SCALINGS}, got {scaling!r}")
    by_class = dataset.by_class("train")
    return fit_class_models(by_class, beta, lambda_cseq, n_steps, init, random_state, progress, scaling)


def fit_class_models(
    by_class: dict[str, list[np.ndarray]],
    beta: float | str = "auto",
    lambda_cseq: float = 1.0,
    n_steps: int = 300,
    init: str = "equidistant",
    random_state: int | None = 0,
    progress: Callable[[str], None] | None = None,
    scaling: str = "standard",
) -> dict:
    """:func:`train_class_models` on label → list of (T, d) training segments."""
    from handflow.plugins.manifold import StructuredUKR

    if init not in INITS:
        raise ValueError(f"init must be one of {INITS}, got {init!r}")
    scaler = ChannelScaling().fit([s for seqs in by_class.values() for s in seqs]) if scaling == "standard" else None
    models = {}
    for label, seqs in by_class.items():
        if scaler is not None:
            seqs = [scaler.transform(s) for s in seqs]
        b = auto_beta(seqs) if beta == "auto" else float(beta)
        if progress:
            progress(f"training '{label}' on {len(seqs)} sequences ({sum(map(len, seqs))} points, beta={b:.1f})")
        models[label] = StructuredUKR(
            latent=[{"kernel": "periodic", "beta": b, "time": True}],
            lambda_cseq=lambda_cseq,
            lambda_pvar=0.0,
            n_steps=n_steps,
            init=init,
            random_state=random_state,
        ).fit(seqs)
        if scaler is not None:
            models[label].provenance_ = dict(models[label].provenance_, **scaler.to_provenance())
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
