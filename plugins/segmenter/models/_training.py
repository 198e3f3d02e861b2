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
import multiprocessing
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from contextlib import nullcontext
from functools import partial
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from ..compatibility import evidence_temperature
from ..datasets import LabelledDataset
from ..features import ChannelScaling, DelayEmbedding, Derived, FeaturePipeline, Headings
from ..novelty import IntensityRanges
from ._candidates import INDEX_FILE, CandidateSet, UKRCandidate
from ._cycles import phase_direction, split_cycles


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


def periodic_class_model(
    sequences: list[np.ndarray],
    beta: float,
    kernel: str = "periodic",
    lambda_cseq: float = 1.0,
    init: str = "equidistant",
    **options,
):
    """A StructuredUKR with one periodic latent time dimension fitted on a class's sequences
    (``λ_pvar = 0`` as for the thesis' 1D models); ``options``: ``n_steps``, ``random_state``."""
    from handflow.plugins.manifold import StructuredUKR

    return StructuredUKR(
        latent=[{"kernel": kernel, "beta": beta, "time": True}],
        lambda_cseq=lambda_cseq,
        lambda_pvar=0.0,
        init=init,
        **options,
    ).fit(sequences)


def class_pieces(segments: list[np.ndarray], cycles: str, max_points: int | None) -> tuple[list[np.ndarray], bool]:
    """Training sequences of one class and whether they are cycles of a periodic motion.

    ``cycles="auto"`` cuts every segment into single cycles (:func:`._cycles.split_cycles`;
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
    headings: tuple[int, ...] = (),
) -> dict:
    """One StructuredUKR per class from label → list of (T, d) training segments.

    ``scaling="standard"`` (default) z-scores every channel with the statistics of all training
    observations (:mod:`..features`); ``"none"`` trains on the raw channels.  ``cycles`` see
    :func:`class_pieces`.  Each model's provenance records the scaling and ``open_stroke``: True
    when the class was trained on whole segments (one stroke per period), False when on cycles
    of a periodic motion.  ``kernel="periodic_quartic"`` (compact, see :data:`KERNELS`) trains
    on all pieces, ignoring ``max_points``, in time linear in the number of points.
    ``headings``: column indices whose heading (direction of motion, :mod:`..features`) is
    appended to every observation before the scaling; stored in each model's provenance.
    """
    if init not in INITS:
        raise ValueError(f"init must be one of {INITS}, got {init!r}")
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
    compact = kernel == "periodic_quartic"
    if scaling not in SCALINGS:
        raise ValueError(f"scaling must be one of {SCALINGS}, got {scaling!r}")
    heading = Headings(tuple(headings)).fit([s for seqs in by_class.values() for s in seqs])
    by_class = {label: [heading.transform(s) for s in seqs] for label, seqs in by_class.items()}
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
        model = periodic_class_model(
            seqs, b, kernel=kernel, lambda_cseq=lambda_cseq, n_steps=n_steps, init=init, random_state=random_state
        )
        model.provenance_ = dict(
            model.provenance_,
            **(scaler.to_provenance() if scaler else {}),
            **(heading.to_provenance() if heading.active else {}),
            open_stroke=not periodic,
        )
        models[label] = model
    return models


MAX_POINTS_PER_CLASS = 800  # UKR training points per class of fit_recording_models (thin_pieces above it)
MIN_PERIOD = 5  # frames; the shortest cycle fit_recording_models looks for
MAX_STATISTICS_FRAMES = 4000  # training frames per class whose errors set the models' metric (thin_pieces above it)


def thin_pieces(pieces: list[np.ndarray], max_points: int) -> list[np.ndarray]:
    """Evenly spaced whole pieces holding at most ``max_points`` observations in all (documented
    choice: every kept piece keeps its full time resolution; one piece at least, cut to ``max_points``)."""
    stride = max(1, int(np.ceil(sum(map(len, pieces)) / max_points)))
    kept = pieces[::stride]
    while len(kept) > 1 and sum(map(len, kept)) > max_points:
        kept = kept[::2]
    return kept if sum(map(len, kept)) <= max_points else [kept[0][:max_points]]


def fit_recording_models(
    by_class: dict[str, list[np.ndarray]],
    delay: int = 8,
    n_steps: int = 150,
    random_state: int | None = 0,
    scaling: str = "none",
    progress: Callable[[str], None] | None = None,
    derived: str = "none",
    max_points: int = MAX_POINTS_PER_CLASS,
    statistics_frames: int = MAX_STATISTICS_FRAMES,
    jobs: int = 1,
) -> CandidateSet:
    """Class models for real recordings (docs/segmentation.md, "Class models for real recordings"):
    label → training segments (T, d), each holding any number of repetitions.

    Each segment is delay-embedded (``delay`` frames, :mod:`..features`; complete windows only), cut
    into cycles (period detection on the embedded class data, :func:`._cycles.split_cycles`), and one
    periodic StructuredUKR per class is fitted on at most ``max_points`` evenly thinned points
    (:data:`MAX_POINTS_PER_CLASS`).  Documented choice: errors are measured in one metric for all models — Σ =
    the variance of all classes' embedded training frames, one ``error_reference`` (the median
    error of the training frames on their own class's model) — and each model stores its own
    typical error relative to it (``own_error``) and the evidence temperature of the training
    frames (``evidence_temperature``), as :class:`CLMSegmenter`'s ``reconstruction="relative"``
    uses them, and the range of its training frames' motion intensity (:mod:`..novelty`).  The
    errors behind those statistics are those of at most ``statistics_frames`` evenly thinned
    frames per class (:data:`MAX_STATISTICS_FRAMES`) (whole segments; documented choice: a fit then costs the same
    however long the recordings grow).
    ``scaling="standard"`` z-scores the channels with all training frames first and stores the
    scaling with the models (for models used outside the evaluation).  ``derived="velocities"``
    appends each channel's step to every frame first (:mod:`..features`; the models derive them from
    raw streams as they were trained).  ``jobs`` > 1 fits the class manifolds over that many forked
    processes, one BLAS thread each (:func:`_fit_manifolds`; the same models as one after the other).
    """
    if scaling not in SCALINGS:
        raise ValueError(f"scaling must be one of {SCALINGS}, got {scaling!r}")
    features = Derived(derived)
    frames = {c: [features.complete(s) for s in segs] for c, segs in by_class.items()}
    scaler = ChannelScaling().fit([s for segs in frames.values() for s in segs]) if scaling == "standard" else None
    embedding = DelayEmbedding(int(delay))
    embedded = {
        c: [embedding.complete(scaler.transform(s) if scaler else s) for s in segs] for c, segs in frames.items()
    }
    pooled_variance = np.vstack([e for segs in embedded.values() for e in segs]).var(axis=0)
    pooled_variance = np.where(pooled_variance > 0, pooled_variance, 1.0)
    extra = {
        **embedding.to_provenance(),
        **features.to_provenance(),
        **(scaler.to_provenance() if scaler else {}),
        "reconstruction": "relative",
    }
    pieces = {}
    for c, segs in embedded.items():
        direction = phase_direction(np.vstack(segs))
        seqs = [cyc for s in segs for cyc in split_cycles(s, direction, MIN_PERIOD) if len(cyc) >= 4] or segs
        pieces[c] = thin_pieces(seqs, max_points)
        if progress:
            progress(f"training '{c}' on {len(pieces[c])} pieces ({sum(map(len, pieces[c]))} points, delay {delay})")
    models = _fit_manifolds(pieces, n_steps, random_state, jobs)
    for model in models.values():
        model.train_variance_ = pooled_variance
        model.provenance_ = dict(model.provenance_, **extra)
    pipeline = FeaturePipeline(features, Headings(), scaler, embedding)
    cands = candidate_set(models, pipeline)
    errors = {  # (frames, M)
        c: np.vstack([cands.project(s).errors for s in thin_pieces(segs, statistics_frames)])
        for c, segs in by_class.items()
    }
    own = {c: errors[c][:, j] for j, c in enumerate(frames)}
    reference = float(np.median(np.concatenate(list(own.values())))) or 1.0
    tau = evidence_temperature(-np.vstack(list(errors.values())) / reference)
    intensity = IntensityRanges().fit(frames)
    for row, (c, model) in enumerate(models.items()):
        model.provenance_ = dict(
            model.provenance_,
            error_reference=reference,
            evidence_temperature=tau,
            own_error=float(np.median(own[c])) / reference,
            **intensity.class_provenance(row),
        )
    final = candidate_set(models, pipeline)  # reads the provenance just written
    final._batched = cands._batched  # the same manifolds: the batched projector is built once per fit
    return final


def _periodic_fit(seqs: list[np.ndarray], n_steps: int, random_state: int | None, one_thread: bool = False):
    """One class manifold of :func:`fit_recording_models` on its pieces (on one BLAS thread: a worker's task)."""
    with threadpool_limits(1) if one_thread else nullcontext():
        return periodic_class_model(seqs, auto_beta(seqs), n_steps=n_steps, random_state=random_state)


def _fit_manifolds(pieces: dict[str, list[np.ndarray]], n_steps: int, random_state: int | None, jobs: int) -> dict:
    """Class → periodic manifold fitted on its pieces: one after the other in this process (``jobs`` ≤ 1), or
    over ``jobs`` forked processes with one BLAS thread each.  Each fit depends on its own pieces and seed
    only, so the models are the same either way (tested); documented choice: one BLAS thread, as the
    evaluation's workers fit — a second OpenBLAS thread next to the other worker made a fit of 611 points
    twice as costly in CPU (5.4 against 2.5 s, docs/benchmarks.md, "Teach your own gestures")."""
    if jobs <= 1 or len(pieces) <= 1:
        return {c: _periodic_fit(s, n_steps, random_state) for c, s in pieces.items()}
    with ProcessPoolExecutor(min(jobs, len(pieces)), mp_context=multiprocessing.get_context("fork")) as pool:
        fitted = pool.map(
            partial(_periodic_fit, n_steps=n_steps, random_state=random_state, one_thread=True), pieces.values()
        )
        return dict(zip(pieces, fitted))


def candidate_set(models: dict, pipeline: FeaturePipeline | None = None) -> CandidateSet:
    """Wrap fitted StructuredUKR models as candidates with the feature ``pipeline`` they were
    trained on (None: the one their provenance records)."""
    return CandidateSet({label: UKRCandidate(m) for label, m in models.items()}, pipeline)


def save_class_models(models: dict | CandidateSet, out_dir: str | Path, provenance: dict | None = None) -> Path:
    """Write ``<label>.npz`` per class plus ``classes.json`` (the index read by the recognisers);
    ``models`` maps labels to fitted models, or is a :class:`CandidateSet` of them."""
    if isinstance(models, CandidateSet):
        models = {label: cand.model for label, cand in models.models.items()}
    out = Path(out_dir).expanduser()
    out.mkdir(parents=True, exist_ok=True)
    index = {}
    for label, model in models.items():
        name = f"{label}.npz"
        model.save(out / name, provenance=dict(provenance or {}, label=label))
        index[label] = name
    (out / INDEX_FILE).write_text(json.dumps({"classes": index, "provenance": provenance or {}}, indent=2))
    return out
