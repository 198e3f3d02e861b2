"""Candidate motion models and their projections (docs/segmentation.md, preamble).

A *candidate model* is anything with ``project(Y) -> (latent_time, errors)``: the latent time
``x̂_{t,dt}`` of every observation on that model's periodic time axis (period π) and the
normalised self-reconstruction error ``e_t``.  :class:`UKRCandidate` adapts one trained
:class:`handflow.plugins.manifold.StructuredUKR`; :class:`CandidateSet` holds one model per class and
projects a sequence onto all of them at once, giving a :class:`Projection` that the
recognisers consume (projections are computed once and re-used across parameter settings).
When every candidate is a 1D periodic UKR manifold, :class:`CandidateSet` projects onto all of
them in one batched call (:mod:`._fast_projection`) instead of one ``transform`` per model
(provided they share one channel scaling, :mod:`..features`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from handflow.framework.files.npz import building

from ..features import ChannelScaling, DelayEmbedding, Derived, FeaturePipeline, Headings
from ..novelty import IntensityRanges, log_intensity

INDEX_FILE = "classes.json"
TRAIN_HINT = "train them with `handflow train-classes DATASET --out DIR`"


class ModelsMissingError(FileNotFoundError):
    """No usable trained candidate models; the message says how to train them."""


@runtime_checkable
class CandidateModel(Protocol):
    """What a recogniser needs from one candidate."""

    def project(self, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, d) observations → latent time (N,) in [0, π) and normalised errors e_t (N,)."""


@dataclass
class Projection:
    """Projections of N observations onto M candidates: ``latent_time`` and ``errors`` (N, M);
    ``reversed_errors`` (N, M): the errors with the observations' headings turned round
    (:mod:`..features`; None for candidates without heading channels)."""

    latent_time: np.ndarray
    errors: np.ndarray
    classes: list[str]
    reversed_errors: np.ndarray | None = None

    def __len__(self) -> int:
        return self.latent_time.shape[0]

    def row(self, t: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Observation t's latent times, errors and reversed errors (M,) each (None without heading
        channels): the arguments of an online segmenter's ``update_projected``."""
        return self.latent_time[t], self.errors[t], None if self.reversed_errors is None else self.reversed_errors[t]

    def _select(self, rows, cols, classes: list[str]) -> Projection:
        def pick(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[rows][:, cols]

        return Projection(pick(self.latent_time), pick(self.errors), classes, pick(self.reversed_errors))

    def take(self, index) -> Projection:
        """Rows ``index`` (slice, index array).  For pointwise candidates this equals projecting the
        same sub-sampled / cut / reordered observations; with heading channels or a delay
        embedding, project those observations instead."""
        return self._select(index, slice(None), list(self.classes))

    def without(self, label: str) -> Projection:
        """The same projection with candidate ``label`` left out."""
        keep = [i for i, c in enumerate(self.classes) if c != label]
        return self._select(slice(None), keep, [self.classes[i] for i in keep])

    @staticmethod
    def concatenate(parts: list[Projection]) -> Projection:
        def stack(name: str) -> np.ndarray | None:
            return None if getattr(parts[0], name) is None else np.vstack([getattr(p, name) for p in parts])

        return Projection(stack("latent_time"), stack("errors"), list(parts[0].classes), stack("reversed_errors"))


class UKRCandidate:
    """Adapter: a trained structured UKR manifold as a :class:`CandidateModel`.

    ``e_t = (y_t − ŷ_t)ᵀ Σ⁻¹ (y_t − ŷ_t)`` with ``ŷ_t = f(g(y_t))`` and Σ the diagonal of the
    training-data variances (the estimator's ``reconstruction_error``).

    The sequence-order penalty of UKR is symmetric in direction, so a trained latent time axis may
    run against the chronological order.  Documented choice: ``direction`` is the sign of the mean
    ``sin(2 Δx)`` over consecutive training latents (period π), and latent times are multiplied by
    it, so forward motion always means increasing latent time.

    ``error_reference`` divides ``e_t`` (default: the model's provenance ``error_reference``, else
    1 = the thesis' definition); models for real recordings share one
    (:func:`._training.fit_recording_models`, docs/segmentation.md).

    ``seam``: for a model of an *open stroke* (trained on whole strokes, not cycles; flagged
    ``open_stroke`` in its provenance) the latent time where the stroke's end meets its start on
    the periodic axis (:func:`stroke_seam`); None for periodic motions.  The CLM order ratings
    treat crossing the seam as a restart, not as forward motion
    (:func:`..compatibility.candidate_band`).

    A model trained on scaled channels (:mod:`..features`, stored in its provenance) scales every
    observation the same way before projecting.
    """

    def __init__(self, model, error_reference: float | None = None) -> None:
        self.model = model
        prov = getattr(model, "provenance_", None) or {}
        self.error_reference = float(prov.get("error_reference", 1.0) if error_reference is None else error_reference)
        self.scaling = ChannelScaling.from_model(model)
        self.time_dim = int(getattr(model, "time_dim_", 0) or 0)
        self.direction = training_direction(model.latents_[:, self.time_dim], model.sequence_ids_)
        self.seam = (
            stroke_seam(np.mod(self.direction * model.latents_[:, self.time_dim], np.pi), model.sequence_ids_)
            if prov.get("open_stroke")
            else None
        )

    @property
    def periodic_1d(self) -> bool:
        """True for a model with one periodic latent (time) dimension: batched projection applies."""
        periodic = np.asarray(getattr(self.model, "periodic_", [False]))
        return periodic.shape == (1,) and bool(periodic[0])

    def normalised_errors(self, Y: np.ndarray, reconstruction: np.ndarray) -> np.ndarray:
        """``e_t`` of observations Y (N, d) given their reconstructions ``f(g(y))``."""
        residual = Y - reconstruction
        with np.errstate(over="ignore"):  # an observation astronomically far off has the error inf
            return np.sum(residual * residual / self.model.train_variance_, axis=1) / self.error_reference

    def scaled(self, Y: np.ndarray) -> np.ndarray:
        """Observations in the channel scaling the model was trained in."""
        Y = np.asarray(Y, dtype=float)
        return Y if self.scaling is None else self.scaling.transform(Y)

    def project(self, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        Y = self.scaled(Y)
        X = self.model.transform(Y)
        errors = self.normalised_errors(Y, self.model.inverse_transform(X))
        return np.mod(self.direction * X[:, self.time_dim], np.pi), errors


def training_direction(latent_time: np.ndarray, sequence_ids: np.ndarray) -> float:
    """+1 if latent time increases along the training sequences (mean ``sin(2Δ)`` ≥ 0), else −1."""
    lt = np.asarray(latent_time, dtype=float)
    ids = np.asarray(sequence_ids)
    same = ids[1:] == ids[:-1]
    steps = np.sin(2.0 * (lt[1:] - lt[:-1]))[same]
    return 1.0 if steps.size == 0 or steps.mean() >= 0 else -1.0


def stroke_seam(latent_time: np.ndarray, sequence_ids: np.ndarray) -> float:
    """Latent time between the training strokes' ends and starts (period π): the circular mean
    end plus half the forward gap to the circular mean start."""
    lt = np.asarray(latent_time, dtype=float)
    ids = np.asarray(sequence_ids)
    first = np.r_[True, ids[1:] != ids[:-1]]
    last = np.r_[ids[1:] != ids[:-1], True]

    def circular_mean(x):
        return np.mod(np.angle(np.mean(np.exp(2j * x))) / 2.0, np.pi)

    start, end = circular_mean(lt[first]), circular_mean(lt[last])
    return float(np.mod(end + 0.5 * np.mod(start - end, np.pi), np.pi))


class CandidateSet:
    """One candidate model per class label (labels keep the given order) and the feature pipeline
    that turns observations into their input (:class:`..features.FeaturePipeline`; ``None`` = the
    one the models record in their provenance, as model files do)."""

    def __init__(self, models: dict[str, CandidateModel], pipeline: FeaturePipeline | None = None) -> None:
        if not models:
            raise ModelsMissingError(f"no candidate models given; {TRAIN_HINT}")
        for name, m in models.items():
            if not isinstance(m, CandidateModel):
                raise TypeError(f"candidate {name!r} has no project(Y) method")
        self.models = dict(models)
        self._batched = None
        provenances = [getattr(getattr(m, "model", None), "provenance_", None) or {} for m in self.models.values()]
        if pipeline is None:  # what the models record (model files written before the pipeline was held)
            first = next(iter(self.models.values()))
            scaling = first.scaling if isinstance(first, UKRCandidate) else None
            pipeline = FeaturePipeline.from_provenances(provenances, scaling)
        self.pipeline = pipeline
        self.provenance = provenances[0]  # how the (first) model was trained: dataset, steps, calibration
        self.evidence_temperature = float(provenances[0].get("evidence_temperature", 1.0))
        self.own_errors = np.array([float(p.get("own_error", 1.0)) for p in provenances])
        self.intensity = IntensityRanges.from_provenances(provenances)  # None for models without ranges
        self.reconstruction = str(provenances[0].get("reconstruction", "absolute"))  # what the models were made for
        calibrated = provenances[0].get("background_factor")  # chosen by `train-classes` on recordings
        self.background_factor = None if calibrated is None else float(calibrated)
        history = provenances[0].get("history")  # the CLM neighbourhood `train-classes` chose or calibrated at
        self.history = None if history is None else int(history)

    def _batched_projector(self):
        """The batched projector over all candidates, or None when some are not 1D periodic UKR."""
        if self._batched is None:
            ukr = [m for m in self.models.values() if isinstance(m, UKRCandidate) and m.periodic_1d]
            first = ukr[0].scaling if ukr else None
            shared = all((m.scaling is None) if first is None else first.same_as(m.scaling) for m in ukr)
            if len(ukr) != len(self.models) or not shared:
                self._batched = False
            else:
                from ._fast_projection import BatchedPeriodicProjector

                self._batched = BatchedPeriodicProjector(
                    [m.model.latents_[:, 0] for m in ukr],
                    [m.model.Y_ for m in ukr],
                    [m.model.kernel_.kernels[0].beta for m in ukr],
                )
        return self._batched or None

    @property
    def classes(self) -> list[str]:
        return list(self.models)

    def seams(self) -> np.ndarray:
        """Open-stroke seam per candidate (NaN for periodic motions and non-UKR candidates)."""
        return np.array([s if (s := getattr(m, "seam", None)) is not None else np.nan for m in self.models.values()])

    def __len__(self) -> int:
        return len(self.models)

    @property
    def delay(self) -> DelayEmbedding:
        return self.pipeline.delay

    @property
    def headings(self) -> Headings:
        return self.pipeline.headings

    @property
    def derived(self) -> Derived:
        return self.pipeline.derived

    @property
    def scaling(self) -> ChannelScaling | None:
        """The channel scaling of the pipeline (the candidates'); None for raw channels."""
        return self.pipeline.scaling

    def scaled(self, Y: np.ndarray) -> np.ndarray:
        """Observations in the channel scaling of the pipeline."""
        return self.pipeline.scaled(np.asarray(Y, dtype=float))

    @property
    def stateful(self) -> bool:
        """True when an observation's model input depends on the ones before it (a delay
        embedding, heading channels or velocities): a stream goes through :meth:`stream`."""
        return self.pipeline.stateful

    def stream(self) -> ObservationStream:
        """Prepares a stream's observations one at a time, equal to :meth:`project` of the whole stream."""
        return ObservationStream(self)

    def project(self, Y: np.ndarray, embedded: bool = False, reversed_rows: np.ndarray | None = None) -> Projection:
        """Project (N, d) observations — a contiguous stretch of a stream from its start — onto every
        candidate; candidates trained on velocities (:mod:`..features`), heading channels
        (:mod:`..features`) or a delay embedding (:mod:`..features`) derive, head and embed Y first.
        ``embedded=True``: the rows are already prepared (the online segmenter's stream,
        :meth:`stream`), ``reversed_rows`` with their headings turned round."""
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        if not np.isfinite(Y).all():
            raise ValueError("observations hold NaN/inf; drop or repair those rows before recognition")
        batched = self._batched_projector()
        if self.stateful and batched is None:
            raise ValueError(
                "a delay embedding, heading channels or velocities need 1D periodic UKR candidates with one shared "
                "channel scaling"
            )
        if batched is None:
            lt = np.empty((Y.shape[0], len(self)))
            e = np.empty_like(lt)
            for j, m in enumerate(self.models.values()):
                lt[:, j], e[:, j] = m.project(Y)
            return Projection(lt, e, self.classes)
        if not embedded:
            Y, reversed_rows = self.pipeline.transform_both(Y)
        lt, e = self._batched_project(batched, Y)
        reversed_errors = None if reversed_rows is None else self._batched_project(batched, reversed_rows)[1]
        return Projection(lt, e, self.classes, reversed_errors)

    def _batched_project(self, batched, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        X, F = batched.project(Y)
        lt = np.empty((Y.shape[0], len(self)))
        e = np.empty_like(lt)
        for j, m in enumerate(self.models.values()):
            lt[:, j] = np.mod(m.direction * X[:, j], np.pi)
            e[:, j] = m.normalised_errors(Y, F[:, j])
        return lt, e

    def without(self, label: str) -> CandidateSet:
        return CandidateSet({k: v for k, v in self.models.items() if k != label}, self.pipeline)

    def intensity_weights(self, Y: np.ndarray) -> np.ndarray:
        """Per observation and candidate (N, M), how far Y's motion intensity lies within the
        candidate's training range (:mod:`..novelty`); all 1 for models without ranges."""
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        if self.intensity is None:
            return np.ones((len(Y), len(self)))
        derived = self.derived.transform(Y)
        return self.intensity.weights(log_intensity(derived, self.intensity.floor, self.intensity.window))

    @property
    def n_channels(self) -> int:
        """Channels of an observation, before the derived features, the heading channels and the delay
        embedding."""
        embedded = next(iter(self.models.values())).model.n_features_in_ // int(self.delay.window)
        return (embedded - len(self.headings.channels)) // self.derived.factor


class ObservationStream:
    """A stream's observations prepared one at a time for :meth:`CandidateSet.project` with
    ``embedded=True``: derived (:mod:`..features`), headed (:mod:`..features`), scaled and
    delay-embedded (:mod:`..features`)."""

    def __init__(self, candidates: CandidateSet) -> None:
        self.candidates = candidates
        self._features = candidates.pipeline.stream()
        self._derived_for_intensity = candidates.derived.stream()  # advanced by intensity_weights alone
        self._intensity = candidates.intensity.stream() if candidates.intensity else None

    def project(self, y: np.ndarray) -> Projection:
        """Projection (one row) of the stream's newest observation y (d,) onto the candidates."""
        c = self.candidates
        if not c.stateful:
            return c.project(y)
        rows, reversed_rows = self.push(np.asarray(y, dtype=float).reshape(-1))
        return c.project(rows, embedded=True, reversed_rows=reversed_rows)

    def intensity_weights(self, y: np.ndarray) -> np.ndarray:
        """(1, M) intensity weights of the newest observation y (d,), equal to
        :meth:`CandidateSet.intensity_weights` of the whole stream (all 1 for models without ranges)."""
        c = self.candidates
        if self._intensity is None:
            return np.ones((1, len(c)))
        return c.intensity.weights(self._intensity.push(self._derived_for_intensity.push(y)))

    def push(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """The prepared row (1, D) of the newest observation y (d,), and the row with its heading
        turned round (None without heading channels)."""
        return self._features.push(y)


def _load_ukr(path: Path):
    from handflow.plugins.manifold import StructuredUKR

    return StructuredUKR.load(path)


def model_files(source: str | Path | list[str | Path]) -> dict[str, Path]:
    """Resolve a folder written by ``train-classes`` (or a list of model files) to label → file.

    A folder must hold ``classes.json`` (``{"classes": {label: file}}``); a model file's label is
    its file-name stem.
    """
    if isinstance(source, (str, Path)):
        folder = Path(source).expanduser()
        if folder.is_dir():
            index = folder / INDEX_FILE
            if not index.exists():
                raise ModelsMissingError(f"{folder} holds no {INDEX_FILE}; {TRAIN_HINT}")
            with building(index, "class index", TRAIN_HINT):
                entries = json.loads(index.read_text())["classes"]
                files = {str(label): folder / name for label, name in entries.items()}
        else:
            files = {folder.stem: folder}
    else:
        files = {Path(p).stem: Path(p).expanduser() for p in source}
    missing = [str(p) for p in files.values() if not p.exists()]
    if missing or not files:
        raise ModelsMissingError(f"model file(s) {missing or [str(source)]} not found; {TRAIN_HINT}")
    return files


def load_candidates(source: str | Path | list[str | Path], loader=_load_ukr) -> CandidateSet:
    """Load trained candidate manifolds (see :func:`model_files`) as a :class:`CandidateSet`."""
    candidates = {}
    for label, path in model_files(source).items():
        model = loader(path)
        with building(path, "class model", TRAIN_HINT):
            candidates[label] = UKRCandidate(model)
    return CandidateSet(candidates)
