"""Runtime nodes ``segmenter.online_clm`` and ``segmenter.ukr_only`` (thin wrappers, docs/segmentation.md).

Both take observations on one of two ports — ``joints`` (JointState; positions, optionally
re-ordered by the ``joints`` parameter) or ``array`` (Array; flattened) — and publish a
:class:`Label` per observation on ``labels`` and :class:`SegmentEvent` s on ``events``
(``start``/``end`` when the newest label changes; the CLM node also ``revision`` when later
evidence changes an earlier label).  Output stamps are the observation's stamp.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator
from threadpoolctl import ThreadpoolController

from handflow.framework.files.inputs import InputPath
from handflow.framework.files.npz import format_check
from handflow.framework.files.params import StrictModel, live
from handflow.framework.messages import Array, JointState, Label, Message, MessageError, SegmentEvent
from handflow.framework.plugin import Node
from handflow.plugins.manifold.io import FORMAT as UKR
from handflow.plugins.manifold.io import FORMAT_VERSION as UKR_VERSION

from .clm import UKROnlyRecognizer
from .datasets import ADAPTATIONS
from .features import ChannelScaling, RunningStandardizer
from .models import CandidateSet, enrolled_models, load_candidates, model_files
from .online import OnlineCLMSegmenter, OnlineScoreCLMSegmenter, SegmentChange, SegmentTracker
from .scorers import FORMAT, FORMAT_VERSION, MiniRocketScorer, ScorerFileError, WindowScorer, load_scorer

UNKNOWN = "unknown"
UKR_FORMAT = (UKR, UKR_VERSION, "format_version")
_TRAIN = "train them with `handflow train-classes` (docs/segmentation.md)"
_FIT = "fit one with `handflow fit-scorer` (docs/segmentation.md)"
_MODEL_FORMAT = format_check("class model", _TRAIN, UKR_FORMAT)


def check_models(path: Path) -> None:
    """Preflight of ``models``: what the node reads at start — a folder's ``classes.json`` and the
    model files it names (:func:`.model_files`), or one model file — each model's format and version,
    without building the models (docs/pipelines.md, "Inputs")."""
    for file in model_files(path).values():
        _MODEL_FORMAT(file)


Models = Annotated[str, InputPath("any", "class models", _TRAIN, check=check_models)]
"""A folder written by `handflow train-classes`, or one model file (its index, format and version checked)."""
Scorer = Annotated[
    str,
    InputPath(what="scorer file", hint=_FIT, check=format_check("scorer", _FIT, (FORMAT, FORMAT_VERSION, "version"))),
]


def running_normaliser(scaling: ChannelScaling | None, frames: int) -> Callable[[np.ndarray], np.ndarray]:
    """Observation → the observation standardised causally (:class:`.RunningStandardizer` with
    ``frames`` prior frames at the models' channel ``scaling``), mapped back into raw units so that
    the models' scaling gives the standardised value (docs/segmentation.md)."""
    if scaling is None:
        raise ValueError(
            "running_normalisation_frames needs models that store their channel scaling; "
            "retrain them with `handflow train-classes`"
        )
    stream = RunningStandardizer(prior_frames=frames).set_prior(scaling.offset_, scaling.scale_).stream()
    return lambda y: scaling.inverse_transform(stream.push(y))


DEFAULT_HISTORY = 10
"""The CLM neighbourhood H of the nodes when neither the parameter nor the models (``train-classes``) set it."""


class RecognizerParams(StrictModel):
    models: Models | list[Models] = Field(description="folder written by `handflow train-classes`, or model files")
    history: int = Field(DEFAULT_HISTORY, ge=1, description="H: history length / CLM neighbourhood")
    joints: list[str] = Field(
        default_factory=list,
        description="joint names to use, in model column order (empty: all positions as they come)",
    )


class _RecognizerNode(Node):
    """Shared input handling, model loading and message building; subclasses define ``recognise``.

    Documented choice: a recogniser computes on one BLAS thread (:meth:`one_blas_thread`).  Its
    products are small (one observation against every candidate's training points); a second
    OpenBLAS thread made each update slower and tripled its CPU time (6.2 against 2.1 ms of CPU per
    observation, 4.9 against 2.2 ms wall, for 3 gesture models; docs/benchmarks.md, "Teach your own
    gestures"), and its spinning takes a core from the other nodes.  The labels are the same.
    """

    inputs = {"joints": JointState, "array": Array}
    outputs = {"labels": Label, "events": SegmentEvent}
    _blas: ThreadpoolController | None = None  # the process's BLAS libraries, found once

    @classmethod
    def one_blas_thread(cls):
        """A context in which BLAS runs on one thread (the previous limits restored after it; ~10 µs)."""
        if _RecognizerNode._blas is None:
            _RecognizerNode._blas = ThreadpoolController()
        return _RecognizerNode._blas.limit(limits=1, user_api="blas")

    def load_models(self, src: str | list[str] | None = None) -> CandidateSet:
        src = self.params.models if src is None else src
        paths = [self.ctx.resolve_path(p) for p in src] if isinstance(src, list) else self.ctx.resolve_path(src)
        return load_candidates(paths)

    def observation(self, port: str, msg: Message) -> np.ndarray:
        if port == "array":
            return np.asarray(msg.values, dtype=float).reshape(-1)
        if not self.params.joints:
            return np.asarray(msg.positions, dtype=float)
        pos = dict(zip(msg.names, msg.positions))
        missing = [j for j in self.params.joints if j not in pos]
        if missing:
            raise ValueError(f"JointState lacks joints {missing}; fix the node's 'joints' parameter")
        return np.array([pos[j] for j in self.params.joints])

    def name(self, label: int) -> str:
        return UNKNOWN if label < 0 else self.classes[label]

    def publish_events(self, events: list[SegmentChange], stamp: int) -> None:
        for ev in events:
            self.ctx.publish(
                "events",
                SegmentEvent(
                    kind=ev.kind,
                    label=self.name(ev.label),
                    start_index=ev.start,
                    end_index=ev.end,
                    previous_label="" if ev.previous is None else self.name(ev.previous),
                ),
                stamp_ns=stamp,
            )

    def on_message(self, port: str, msg: Message) -> None:
        try:
            y = self.observation(port, msg)
            with self.one_blas_thread():
                self.recognise(y, msg.header.stamp_ns)
        except ValueError as exc:  # the runtime drops, counts and logs it (docs/robustness.md)
            raise MessageError(f"observation dropped: {exc}") from None


class OnlineCLMNode(_RecognizerNode):
    """Online CLM segmentation over a sliding window: fast labels on arrival, final labels from
    batch solves of the window, by revision (docs/segmentation.md §C) — over the UKR manifolds
    (``source: ukr``) or a fitted frame scorer's evidence (``minirocket``, ``dtw``)."""

    class Params(RecognizerParams):
        models: Models | list[Models] | None = Field(
            None, description="source ukr: folder written by `handflow train-classes`, or model files"
        )
        source: Literal["ukr", "minirocket", "dtw"] = Field(
            "ukr", description="what the CLM groups: UKR manifolds (models) or a fitted scorer's class scores (scorer)"
        )
        scorer: Scorer | None = Field(None, description="source minirocket/dtw: file written by `handflow fit-scorer`")
        novelty_models: Models | list[Models] | None = Field(
            None,
            description="source minirocket/dtw: class manifolds (`handflow train-classes RECORDINGS --delay 8`) "
            "whose novelty weight scales the scorer's evidence, so motion they do not explain (in shape, or in "
            "intensity: gentler or more vigorous than their training) is rejected",
        )
        novelty: float = live(
            0.25, gt=0, description="novelty weight < 1 beyond 1/novelty times a manifold's own typical error"
        )
        distance_z: float | None = live(
            None,
            description="source minirocket: scale the evidence down where the window's features lie beyond this "
            "robust z-score from every training window (docs/segmentation.md, feature novelty; null = off)",
        )
        history: int | None = Field(
            None,
            ge=1,
            description="H: history length / CLM neighbourhood; null = the one `train-classes` stored with the "
            "models (source ukr: the evaluation's choice with --params, else the history of its calibration), else 10",
        )
        window: int = Field(200, ge=2, description="observations in the sliding window")
        background_factor: float | None = live(
            None,
            ge=0,
            description="multiplies λ_bg (3 = strong background; 0 = none); null = the level `train-classes` "
            "calibrated for the models (source ukr), the null class of null_score (source minirocket/dtw, when "
            "there is one and neither novelty_models nor distance_z is set), else 1",
        )
        null_score: float | None = Field(
            None,
            description="source minirocket/dtw: the background is a null class scoring this on every observation, "
            "a rejection threshold on the scorer's scale (docs/segmentation.md, rejection on the scorer's scale; "
            "-.inf = no rejection); null = the score `fit-scorer` calibrated and stored in the scorer file, if any. "
            "Not with background_factor, novelty_models or distance_z, which reject with the background factor",
        )
        background: float | None = Field(None, description="λ_bg; null = 1 − 10/N")
        error_scale: float = Field(1.0, gt=0, description="multiplies e_t before c_sre (1 = spec)")
        reconstruction: Literal["auto", "absolute", "relative"] = Field(
            "auto",
            description="how UKR errors enter the CLM (docs/segmentation.md); auto = what the models were trained for",
        )
        order_rating: Literal["sign", "cos"] = "sign"
        min_span: int = Field(
            0, ge=0, description="source ukr: the CLM neighbourhood covers at least this many observations (0 = H)"
        )
        min_progress: float = Field(
            0.0,
            ge=0,
            description="source ukr: final segments covering less than this share of their manifold's period are "
            "rejected (0 = off; 0.3 for letters, docs/segmentation.md)",
        )
        max_fit_ratio: float | None = Field(
            None,
            ge=1,
            description="source ukr: final segments whose model fits them worse than this many times the best-fitting "
            "model are rejected (null = off; 2 for letters, docs/segmentation.md)",
        )
        tail: int = Field(30, ge=1, description="newest observations the fast CLM run solves per update")
        update_eta: float = Field(0.9, gt=0, le=1, description="annealing factor per sweep of the fast run")
        update_sweeps: int = Field(
            60, ge=1, description="sweep budget of the fast CLM run per update (labels on arrival)"
        )
        block: int | None = Field(
            None, ge=0, description="observations finalised per block run (null = window/2, 0 = none)"
        )
        block_sweeps: int | None = Field(
            None, ge=1, description="sweeps of the running block run per update (null = 1000 sweeps / block)"
        )
        confirm: int = Field(5, ge=1, description="updates a changed earlier label must hold before a revision")
        running_normalisation_frames: int = Field(
            0,
            ge=0,
            description="source ukr: standardise every observation causally with the stream's running mean/std, "
            "this many pseudo-frames at the models' channel scaling as the prior (docs/segmentation.md); 0 = off",
        )
        lag: int = Field(
            0,
            ge=0,
            description="publish each observation's label from the evidence of the window ending this many "
            "observations later (index = newest − lag; docs/segmentation.md, labels with a lag)",
        )
        enroll: str | None = Field(
            None,
            description="source ukr: a short labelled recording of the session (CSV folder or continuous .npz) whose "
            "first enroll_segments segments per class of the models adapt them at setup, as `evaluate segmentation "
            "--enroll` does (docs/segmentation.md, Enrolment)",
        )
        enroll_segments: int = Field(1, ge=1, description="with enroll: segments per class that enrol (K)")
        enroll_adaptation: Literal[ADAPTATIONS] = Field(
            ADAPTATIONS[0],
            description="with enroll: 'align' refits the models on recordings standardised with their own enrolment "
            "frames and standardises the stream with the session's; 'refit' adds the segments only",
        )
        enroll_training: str | None = Field(
            None,
            description="with enroll: the recordings the models were trained on (null = the dataset their "
            "provenance names)",
        )
        seed: int | None = 0

        @model_validator(mode="after")
        def _source_file(self):
            if self.source == "ukr" and not self.models:
                raise ValueError("source 'ukr' needs 'models' (a folder from `handflow train-classes`)")
            if self.source != "ukr" and not self.scorer:
                raise ValueError(f"source '{self.source}' needs 'scorer' (a file from `handflow fit-scorer`)")
            if self.source == "ukr" and self.novelty_models:
                raise ValueError("novelty_models needs source minirocket or dtw (the UKR source rejects by itself)")
            if self.source != MiniRocketScorer.kind and self.distance_z is not None:
                raise ValueError("distance_z needs source minirocket (the only scorer with features)")
            if self.null_score is not None and self.source == "ukr":
                raise ValueError("null_score needs source minirocket or dtw (a threshold on the scorer's scale)")
            if self.null_score is not None and (
                self.background_factor is not None or self.novelty_models or self.distance_z is not None
            ):
                raise ValueError(
                    "null_score rejects on the scorer's scale, background_factor, novelty_models and distance_z "
                    "with the background factor: choose one (docs/segmentation.md)"
                )
            if self.source != "ukr" and self.min_progress:
                raise ValueError("min_progress needs source 'ukr' (a scorer's evidence has no latent time)")
            if self.source != "ukr" and self.max_fit_ratio is not None:
                raise ValueError("max_fit_ratio needs source 'ukr' (a scorer's evidence has no model errors)")
            if self.source != "ukr" and self.enroll:
                raise ValueError("enroll needs source 'ukr' (refit the scorer with `handflow fit-scorer` instead)")
            if self.enroll and self.enroll_adaptation == "align" and self.running_normalisation_frames:
                raise ValueError(
                    "enroll_adaptation 'align' standardises the stream with the session's enrolment; "
                    "set running_normalisation_frames 0 or enroll_adaptation refit"
                )
            if self.source != "ukr" and self.running_normalisation_frames:
                raise ValueError("running_normalisation_frames needs source 'ukr' (its prior is the models' scaling)")
            return self

    def setup(self) -> None:
        p = self.params
        models = self.load_models() if p.source == "ukr" else None
        common = dict(
            window=p.window,
            history=_first_set(p.history, models.history if models is not None else None, DEFAULT_HISTORY),
            background=p.background,
            error_scale=p.error_scale,
            order_rating=p.order_rating,
            tail=p.tail,
            update_eta=p.update_eta,
            update_sweeps=p.update_sweeps,
            block=p.block,
            block_sweeps=p.block_sweeps,
            confirm=p.confirm,
            random_state=p.seed,
        )
        self.running = None
        if models is not None:
            if p.enroll:
                models = self.enrolled(models)
            channels = models.n_channels
            reconstruction = models.reconstruction if p.reconstruction == "auto" else p.reconstruction
            self.background_default = _first_set(models.background_factor, 1.0)
            self.segmenter = OnlineCLMSegmenter(
                models,
                background_factor=_first_set(p.background_factor, self.background_default),
                reconstruction=reconstruction,
                min_span=p.min_span,
                min_progress=p.min_progress,
                max_fit_ratio=p.max_fit_ratio,
                **common,
            )
            if p.running_normalisation_frames:
                if models.headings.active:
                    raise ValueError(
                        "running_normalisation_frames does not apply to models with heading channels "
                        "(docs/segmentation.md); set it to 0 or retrain without --headings"
                    )
                self.running = running_normaliser(models.scaling, p.running_normalisation_frames)
        else:
            scorer = self.load_scorer()
            channels = scorer.n_features_in_
            novelty_models = self.load_models(p.novelty_models) if p.novelty_models else None
            if novelty_models is not None and novelty_models.n_channels != scorer.n_features_in_:
                raise ValueError(
                    f"novelty_models were trained on {novelty_models.n_channels} channels, the scorer "
                    f"on {scorer.n_features_in_}; train both on the same recordings"
                )
            self.background_default = 1.0
            self.segmenter = OnlineScoreCLMSegmenter(
                scorer,
                background_factor=_first_set(p.background_factor, 1.0),
                null_score=self.null_score(scorer),
                novelty_models=novelty_models,
                novelty=p.novelty,
                distance_z=p.distance_z,
                **common,
            )
        self.classes = self.segmenter.classes_
        self.warm_up(channels)

    def on_params(self, params: Params, changed: frozenset[str]) -> None:
        """``background_factor``, ``novelty`` and ``distance_z`` while running, the stream kept (docs/tuning.md).
        Turning a score source's ``background_factor`` or ``distance_z`` on or off changes how it rejects
        (its null class): that needs a restart."""
        if self.params.source != "ukr":
            for key in {"background_factor", "distance_z"} & changed:
                if (getattr(params, key) is None) != (getattr(self.params, key) is None):
                    raise ValueError(f"{key} turned on or off changes how the node rejects: pass --restart")
        super().on_params(params, changed)
        seg = self.segmenter
        seg.background_factor = _first_set(params.background_factor, self.background_default)
        if hasattr(seg, "novelty"):
            seg.novelty, seg.distance_z = params.novelty, params.distance_z

    def warm_up(self, channels: int) -> None:
        """Build and compile what the first update needs (batched projector, numba solvers) here in
        setup: on the first observation it would stall every node of the process for 1–2 s
        (docs/flagship.md).  The stream and the solver's generator start afresh afterwards, so the
        labels are those without the warm-up."""
        with self.one_blas_thread():
            self.segmenter.update(np.zeros(channels))
        self.segmenter.set_params(random_state=self.params.seed)
        self.segmenter.reset()

    def enrolled(self, models: CandidateSet) -> CandidateSet:
        """``models`` adapted by the ``enroll`` recording (:func:`..models.enrolled_models`); with
        ``align`` every observation is standardised with the session's enrolment frames first."""
        p = self.params
        training = p.enroll_training or models.provenance.get("dataset")
        if training is None:
            raise ValueError("enroll: the models do not name their training recordings; set enroll_training")
        paths = self.ctx.resolve_path(training), self.ctx.resolve_path(p.enroll)
        models, alignment = enrolled_models(models, *paths, p.enroll_segments, p.enroll_adaptation, p.seed)
        if alignment is not None:
            offset, spread = alignment
            self.running = lambda y: (y - offset) / spread
        return models

    def load_scorer(self) -> WindowScorer:
        scorer = load_scorer(self.ctx.resolve_path(self.params.scorer))
        if scorer.kind != self.params.source:
            raise ScorerFileError(
                f"{self.params.scorer} holds a '{scorer.kind}' scorer, but the node's source is "
                f"'{self.params.source}'; set source: {scorer.kind}"
            )
        return scorer

    def null_score(self, scorer: WindowScorer) -> float | None:
        """The null class's score the segmenter rejects with: the ``null_score`` parameter, else the
        one ``fit-scorer`` calibrated (``scorer.null_score_``) unless ``background_factor``,
        ``novelty_models`` or ``distance_z`` is set; None = the background factor rejects
        (docs/segmentation.md, "Score sources")."""
        p = self.params
        if p.background_factor is not None or p.novelty_models or p.distance_z is not None:
            return None
        return scorer.null_score_ if p.null_score is None else p.null_score

    def recognise(self, y: np.ndarray, stamp: int) -> None:
        """Push ``y`` and publish the label of observation ``newest − lag`` from it: the newest
        evidence is that of the window ending ``lag`` observations after the labelled one (events
        move by the lag too; nothing is published for the first ``lag`` observations)."""
        up = self.segmenter.push(y if self.running is None else self.running(y))
        lag = self.params.lag
        if up.index >= lag:
            self.ctx.publish(
                "labels",
                Label(label=self.name(up.label), index=up.index - lag, classes=self.classes, scores=up.scores),
                stamp_ns=stamp,
            )
        moved = [replace(ev, start=max(ev.start - lag, 0), end=ev.end - lag) for ev in up.events if ev.end >= lag]
        self.publish_events(moved, stamp)


def _first_set(*values: float | None) -> float:
    """The first of ``values`` that is not None."""
    return next(v for v in values if v is not None)


class UKROnlyNode(_RecognizerNode):
    """UKR-only recogniser (docs/segmentation.md §A): scores are the overall compatibilities C(t)."""

    class Params(RecognizerParams):
        lam: float = Field(0.3, ge=0, le=1, description="λ: weight of C_rec")
        gamma: float = Field(0.9, ge=0, le=1, description="γ: history discount")
        order_rating: Literal["cos", "sign"] = "cos"
        threshold: float | None = live(None, description="reject when max C < threshold")

    def setup(self) -> None:
        p = self.params
        self.recognizer = UKROnlyRecognizer(
            self.load_models(),
            lam=p.lam,
            gamma=p.gamma,
            history=p.history,
            order_rating=p.order_rating,
            threshold=p.threshold,
        )
        self.classes = self.recognizer.classes_
        self.segments = SegmentTracker()
        self.index = 0

    def on_params(self, params: Params, changed: frozenset[str]) -> None:
        super().on_params(params, changed)
        self.recognizer.threshold = params.threshold  # read at every decision (docs/tuning.md)

    def recognise(self, y: np.ndarray, stamp: int) -> None:
        label, C = self.recognizer.push(y)
        self.ctx.publish(
            "labels", Label(label=self.name(label), index=self.index, classes=self.classes, scores=C), stamp_ns=stamp
        )
        self.publish_events(self.segments.update(self.index, label), stamp)
        self.index += 1
