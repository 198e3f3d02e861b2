"""UKR/CLM segmenter (docs/segmentation.md §B): one CLM layer per candidate plus a background layer.

:class:`CLMSegmenter` turns the projections of a sequence onto the candidate manifolds into banded
layer compatibilities (:func:`layer_compatibilities`) and runs the
:class:`~handflow.plugins.segmenter.clm.CompetitiveLayerModel` on them.  The winning layer of an
observation is its label; the background layer means rejected (−1).
"""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.base import BaseEstimator, clone
from sklearn.exceptions import NotFittedError

from ..base import REJECTED
from ..compatibility import (
    background_band,
    candidate_band,
    evidence_band,
    order_rating,
    pair_error,
    reject_segments,
    score_evidence,
    thesis_background_strength,
)
from ..models import CandidateSet, Projection
from ._solver import CLMResult, CompetitiveLayerModel, clm_energy

RECONSTRUCTIONS = ("absolute", "relative")
ETA = 0.98  # annealing factor per sweep (docs/segmentation.md, documented choices)
ETA_HEADED = 0.998  # ... for candidates with heading channels, whose energy has near-equal minima
SOLVER_PARAMS = ("J", "eta", "tol", "max_sweeps", "inhibition_margin", "spectral")  # once keywords of the segmenter


def default_solver(candidates: CandidateSet | None = None, **params) -> CompetitiveLayerModel:
    """The CLM solver a segmenter of ``candidates`` uses when given none: annealing factor
    :data:`ETA`, or :data:`ETA_HEADED` for candidates with heading channels, and ``params``."""
    headed = candidates is not None and candidates.headings.active
    return CompetitiveLayerModel(**{"eta": ETA_HEADED if headed else ETA, **params})


RUN_MARGIN = 8  # a run's margins, in band widths (docs/segmentation.md, "Long recordings")


def run_stretches(n: int, run_length: int | None, margin: int) -> list[tuple[int, int, int, int]]:
    """``(lo, hi, keep_lo, keep_hi)`` per run over ``n`` observations: each run covers ``lo…hi``
    (at most ``run_length``) and keeps ``keep_lo…keep_hi``; the kept parts tile ``0…n`` and lie
    ``margin`` observations inside their run wherever the sequence goes on."""
    if run_length is None or n <= run_length:
        return [(0, n, 0, n)]
    core = int(run_length) - 2 * int(margin)
    if core < 1:
        raise ValueError(f"run_length {run_length} leaves no observation between margins of {margin}")
    out = []
    for keep_lo in range(0, n, core):
        keep_hi = min(n, keep_lo + core)
        out.append((max(0, keep_lo - margin), min(n, keep_hi + margin), keep_lo, keep_hi))
    return out


def _joined(results: list[CLMResult], stretches, band: np.ndarray, diag: np.ndarray, J: float) -> CLMResult:
    """The runs' kept parts as one result: its energy is the whole sequence's at the strongest
    run's inhibition."""
    x = np.concatenate([r.activities[:, a - lo : b - lo] for r, (lo, _, a, b) in zip(results, stretches)], axis=1)
    temperature = np.concatenate([r.temperature[a - lo : b - lo] for r, (lo, _, a, b) in zip(results, stretches)])
    inhibition = max(r.inhibition for r in results)
    return CLMResult(
        activities=x,
        winners=np.where(x.max(axis=0) > 0.0, x.argmax(axis=0), -1),
        sweeps=max(r.sweeps for r in results),
        converged=all(r.converged for r in results),
        energy=clm_energy(x, band, diag, J, inhibition),
        inhibition=inhibition,
        temperature=temperature,
    )


class _Result:
    """A result of a segmentation; before one, reading it raises ``NotFittedError``."""

    def __set_name__(self, owner, name: str) -> None:
        self.name = name

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        try:
            return obj.__dict__[self.name]
        except KeyError:
            raise NotFittedError(
                f"{type(obj).__name__}.{self.name} exists after a segmentation: call fit_predict(sequence) first"
            ) from None

    def __set__(self, obj, value) -> None:
        obj.__dict__[self.name] = value


class CLMSegmenter(BaseEstimator):
    """Segment a sequence into candidate motions and background with the UKR/CLM method.

    Parameters
    ----------
    candidates : CandidateSet or None, default None
        The trained models, one per class (one CLM layer each); its fitted part.  ``None``
        segments given layer bands only (:meth:`fit_predict_bands`).
    history : int, default 10
        H, the temporal neighbourhood ``0 < j − i ≤ H`` of the compatibilities.
    order_rating : {'sign', 'cos'}, default 'sign'
        Latent-order rating of ``c_loc`` (spec: ``"sign"``; ``"cos"`` also allowed).
    order_path : {'unwrapped', 'direct'}, default 'unwrapped'
        ``"unwrapped"`` (documented choice) rates the net latent progress
        between i and j, ``"direct"`` the spec's ``x̂_j − x̂_i`` (:func:`..compatibility.candidate_band`).
    min_span : int, default 0
        The candidate layers' neighbourhood covers at least this many observations
        (``max(H, min_span)``; 0 = exactly H as in the spec).  Documented choice: at a high
        sampling rate H observations cover too little of a motion for the order ratings to rise
        above the projection noise (real letters at 200 Hz, H = 5: 5 % of a letter).
    pair_error : {'mean', 'endpoints'}, default 'mean'
        ``ē_ij`` of ``c_sre`` (``"mean"`` over ``i…j``, the documented choice, or
        ``"endpoints"``).
    background : float or None, default None
        λ_bg; ``None`` = thesis rule ``1 − 10/N`` (:func:`thesis_background_strength`).
    background_factor : float, default 1.0
        Multiplies λ_bg (1 = weak, 3 = the spec's "strong" background).
    background_radius : int or None, default None
        K_bg; ``None`` = H.
    error_scale : float, default 1.0
        Multiplies the normalised errors ``e_t`` before ``c_sre`` (1 = the spec).
        Documented deviation, selected on validation by the evaluation: with Σ = the training-data
        variance, ``e_t`` of noisy multi-channel data is ~1 even on the right manifold (BasicMotions:
        median 0.97), so ``c_sre ≈ −0.5…−1`` for every candidate, every candidate layer is
        repulsive and the background takes everything; a scale of 0.1 restores the contrast.
    reconstruction : {'absolute', 'relative'}, default 'absolute'
        How the projection errors enter the layers.  ``"absolute"`` (the spec):
        ``f^m_ij = ½ (c_loc_ij + c_sre_ij)`` with ``c_sre = −1 + 2 exp(−ē_ij)`` and the thesis'
        background layer.  ``"relative"`` (documented choice for real recordings,
        docs/segmentation.md): per frame the scaled errors of all candidates and of a *null
        model* that explains every frame at the error ``1 / background_factor`` become evidence,
        a softmax of ``−error_scale·e`` at the candidates' fitted temperature
        (:attr:`.candidates.CandidateSet.evidence_temperature`), and every layer — the null
        model's being the background — gets ``f_ij = ε_i + ε_j − 2/(M+1)`` within H
        (:func:`..compatibility.evidence_band`): a layer is supported where its manifold explains the
        frames better than the others, whatever the absolute error level of the data, and the
        background where even the best-fitting manifold explains a frame worse than
        ``1 / background_factor`` times its own typical error on its training frames
        (:attr:`.candidates.CandidateSet.own_errors`; factor 0 = no background).
    min_progress : float, default 0.0
        A segment that moves less than this many periods forward along its
        candidate's latent time is rejected after the CLM (0 = off, the spec;
        :func:`..compatibility.reject_small_progress`, documented choice); applied by
        :meth:`fit_predict_projected` to the whole sequence, by the online segmenter to each
        block run's window.
    max_fit_ratio : float or None, default None
        A segment whose candidate fits it worse (mean error) than this many times the
        best-fitting candidate is rejected after the CLM (``None`` = off, the spec;
        :func:`..compatibility.reject_poor_fit`, documented choice); applied with ``min_progress``.
    solver : CompetitiveLayerModel or None, default None
        The :class:`CompetitiveLayerModel` that runs the CLM (its ``J``, ``eta``, ``tol``,
        ``max_sweeps``, ``inhibition_margin``, ``spectral``); ``None`` = :func:`default_solver`: η =
        0.98, or 0.998 for candidates with heading channels (documented choice, docs/segmentation.md:
        their energy has near-equal minima that faster annealing picks at random, so the online
        labels could not equal the batch's).  A copy seeded with ``random_state`` runs.
    restarts : int, default 1
        Independent cold runs per sequence; the lowest-energy solution is kept
        (documented choice: the annealed Gauss–Seidel dynamics end in a local minimum of the
        CLM energy — on real letter pairs the true segmentation often has lower energy than a
        single run's result; keeping the best of 3 minimises the same energy better).
    run_length : int or None, default None
        A sequence longer than this is solved in runs over overlapping stretches of at most this
        many observations, each keeping the labels of its middle, :attr:`run_margin` from its ends
        (``None`` = one run over the whole sequence, the spec).  Documented choice (docs/segmentation.md, "Long recordings"):
        the compatibilities reach only the band, and a run over a long sequence costs more per
        observation as its arrays outgrow the caches.
    random_state : int, numpy.random.Generator or None, default None
        Seed of the stochastic solver.
    J, eta, tol, max_sweeps, inhibition_margin, spectral : optional
        Deprecated keywords, set on the solver
        (with a ``DeprecationWarning``): pass ``solver=default_solver(candidates, ...)`` instead.

    The constructor only stores the parameters (scikit-learn convention: ``get_params``,
    ``set_params`` and ``clone`` work); they are checked, and the solver ``solver_`` with its
    generator seeded from ``random_state`` is made, by the first segmentation.

    Attributes
    ----------
    labels_ : ndarray of shape (N,)
        Class index per observation of the last segmented sequence, −1 = background/unknown.
    n_sweeps_ : int
        Sweeps of the kept CLM run.
    energy_ : float
        CLM energy of the kept run.
    converged_ : bool
        Whether the kept run converged within the solver's ``max_sweeps``.
    activities_ : ndarray of shape (L + 1, N)
        Final activities of the candidate layers and the background layer.
    result_ : CLMResult
        The kept run.
    solver_ : CompetitiveLayerModel
        The solver that ran, seeded with ``random_state``.

    Reading a result before :meth:`fit` / :meth:`fit_predict` raises ``NotFittedError``
    (docs/segmentation.md §B; docs/architecture.md, "Estimator style").

    Examples
    --------
    >>> from handflow.plugins.segmenter import LetterGenerator, candidate_set, train_class_models
    >>> ds = LetterGenerator(n_classes=2, random_state=1).dataset((2, 1, 1))
    >>> candidates = candidate_set(train_class_models(ds, n_steps=20, random_state=0))
    >>> Y = ds.test[0].data
    >>> from handflow.plugins.segmenter import CLMSegmenter
    >>> seg = CLMSegmenter(candidates, history=5, random_state=0).fit(Y)
    >>> seg.labels_.shape == (len(Y),), set(seg.labels_.tolist()) <= {-1, 0, 1}
    (True, True)
    """

    SPECTRAL = "eigen"  # how the default solver bounds λ_max (the CLM's exact eigenvalue)
    labels_ = _Result()
    n_sweeps_ = _Result()
    energy_ = _Result()
    converged_ = _Result()
    activities_ = _Result()
    result_ = _Result()

    def __init__(
        self,
        candidates: CandidateSet | None = None,
        *,
        history: int = 10,
        order_rating: str = "sign",
        pair_error: str = "mean",
        order_path: str = "unwrapped",
        min_span: int = 0,
        background: float | None = None,
        background_factor: float = 1.0,
        background_radius: int | None = None,
        solver: CompetitiveLayerModel | None = None,
        error_scale: float = 1.0,
        reconstruction: str = "absolute",
        min_progress: float = 0.0,
        max_fit_ratio: float | None = None,
        restarts: int = 1,
        run_length: int | None = None,
        random_state=None,
        **solver_params,
    ) -> None:
        if solver_params:
            unknown = sorted(set(solver_params) - set(SOLVER_PARAMS))
            if unknown:
                raise TypeError(f"{type(self).__name__} got unexpected keyword arguments {unknown}")
            warnings.warn(
                f"{sorted(solver_params)} of {type(self).__name__} are deprecated and go in the next release: "
                "pass solver=default_solver(candidates, ...) (a CompetitiveLayerModel) instead",
                DeprecationWarning,
                stacklevel=2,
            )
            base = default_solver(candidates) if solver is None else clone(solver)
            solver = base.set_params(**{k: v for k, v in solver_params.items() if v is not None})
        self.candidates = candidates
        self.history = history
        self.order_rating = order_rating
        self.pair_error = pair_error
        self.order_path = order_path
        self.min_span = min_span
        self.background = background
        self.background_factor = background_factor
        self.background_radius = background_radius
        self.solver = solver
        self.error_scale = error_scale
        self.reconstruction = reconstruction
        self.min_progress = min_progress
        self.max_fit_ratio = max_fit_ratio
        self.restarts = restarts
        self.run_length = run_length
        self.random_state = random_state

    def set_params(self, **params):
        self.__dict__.pop("solver_", None)
        return super().set_params(**params)

    def _solver(self) -> CompetitiveLayerModel:
        """The CLM solver, made (parameters checked, generator seeded) on first use."""
        if "solver_" not in self.__dict__:
            if int(self.restarts) < 1:
                raise ValueError(f"restarts must be >= 1, got {self.restarts}")
            if not self.error_scale > 0:
                raise ValueError(f"error_scale must be > 0, got {self.error_scale}")
            if self.reconstruction not in RECONSTRUCTIONS:
                raise ValueError(f"reconstruction must be one of {RECONSTRUCTIONS}, got {self.reconstruction!r}")
            if int(self.history) < 1:
                raise ValueError(f"history H must be >= 1, got {self.history}")
            if self.run_length is not None and int(self.run_length) < 4 * self.run_margin:
                raise ValueError(
                    f"run_length must be at least {4 * self.run_margin} observations (twice its two margins of "
                    f"{RUN_MARGIN} band widths) or None (one run), got {self.run_length}"
                )
            if not float(self.min_progress) >= 0:
                raise ValueError(f"min_progress must be >= 0 periods, got {self.min_progress}")
            if self.max_fit_ratio is not None and not float(self.max_fit_ratio) >= 1:
                raise ValueError(f"max_fit_ratio must be >= 1 (or None = off), got {self.max_fit_ratio}")
            if self.solver is not None and not isinstance(self.solver, CompetitiveLayerModel):
                raise ValueError(f"solver must be a CompetitiveLayerModel (or None), got {type(self.solver).__name__}")
            solver = default_solver(self.candidates) if self.solver is None else clone(self.solver)
            self.solver_ = solver.set_params(random_state=self.random_state)
        return self.solver_

    @property
    def classes_(self) -> list[str]:
        if self.candidates is None:
            raise ValueError("this CLMSegmenter has no candidates (it segments given layer bands only)")
        return self.candidates.classes

    def background_strength(self, n: int) -> float:
        base = thesis_background_strength(n) if self.background is None else float(self.background)
        return base * self.background_factor

    @property
    def run_margin(self) -> int:
        """Observations between a run's kept part and its ends (``run_length``): :data:`RUN_MARGIN` band widths."""
        return RUN_MARGIN * self.widths()[2]

    def widths(self) -> tuple[int, int, int]:
        """Background radius K_bg, candidate neighbourhood ``max(H, min_span)`` and band width."""
        span = max(int(self.history), int(self.min_span))
        radius = span if self.background_radius is None else int(self.background_radius)
        return radius, span, max(span, radius - 1)

    def layer_compatibilities(self, proj: Projection) -> tuple[np.ndarray, np.ndarray]:
        """Bands (M+1, N, B) and diagonals (M+1,) of all layers, background last."""
        self._solver()  # checks the parameters
        _, span, width = self.widths()
        if self.reconstruction == "relative":
            evidence = self.relative_evidence(proj.errors * float(self.error_scale))
            return self.with_background(evidence_band(evidence, width, span))
        cand = candidate_band(
            proj.latent_time,
            proj.errors * float(self.error_scale),
            width,
            order_rating(self.order_rating),
            pair_error(self.pair_error),
            self.order_path,
            self.candidates.seams(),
        )
        cand[:, :, span:] = 0.0
        return self.with_background(cand)

    def relative_evidence(self, scaled_errors: np.ndarray) -> np.ndarray:
        """Evidence (N, M+1) of ``reconstruction="relative"`` from errors (N, M) already multiplied
        by ``error_scale``; the null model (the background) is the last column.  Per frame: it
        depends on nothing but that frame's errors."""
        E = np.asarray(scaled_errors, dtype=float)
        factor = float(self.background_factor)
        if factor > 0:  # the null model's error: 1/factor times the best-fitting model's own typical error
            own = self.candidates.own_errors[np.argmin(E, axis=1)]
            null = (float(self.error_scale) / factor * own)[:, None]
            return score_evidence(-np.hstack([E, null]), self.candidates.evidence_temperature)
        return np.hstack([score_evidence(-E, self.candidates.evidence_temperature), np.zeros((len(E), 1))])

    def with_background(self, cand: np.ndarray, length: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Candidate bands (M, N, B) → all layers' bands and diagonals, the background layer last;
        λ_bg is that of a sequence of ``length`` observations (default N).  With
        ``reconstruction="relative"`` the bands already end with the background's."""
        if self.reconstruction == "relative":  # a copy: the online segmenter slides its bands in place
            return cand.copy(), np.zeros(cand.shape[0])
        n = cand.shape[1]
        radius, _, width = self.widths()
        bg, bg_diag = background_band(n, width, self.background_strength(n if length is None else length), radius)
        band = np.concatenate([cand, bg[None]], axis=0)
        diag = np.r_[np.zeros(cand.shape[0]), bg_diag]
        return band, diag

    def labels_from(self, result: CLMResult) -> np.ndarray:
        """Layer winners → class indices, background (last layer) and undecided → −1."""
        background = result.activities.shape[0] - 1
        return np.where((result.winners == background) | (result.winners < 0), REJECTED, result.winners)

    @property
    def segment_rules(self) -> bool:
        """Whether segments are judged after the CLM (``min_progress``, ``max_fit_ratio``)."""
        return bool(self.min_progress) or self.max_fit_ratio is not None

    def reject_segments(
        self,
        labels: np.ndarray,
        latent_time: np.ndarray,
        errors: np.ndarray,
        open_ends: tuple[bool, bool] = (False, False),
        reversed_errors: np.ndarray | None = None,
    ) -> np.ndarray:
        """``labels`` with the segments the rules reject set to −1 (:func:`..compatibility.reject_segments`)."""
        return reject_segments(
            labels, latent_time, errors, float(self.min_progress), self.max_fit_ratio, open_ends, reversed_errors
        )

    def fit_predict_projected(self, proj: Projection) -> np.ndarray:
        """Segment an already projected sequence; returns class indices (−1 = background), segments
        the rules reject (``min_progress``, ``max_fit_ratio``) set to −1."""
        if len(proj) < 1:
            raise ValueError("cannot segment an empty sequence")
        labels = self.fit_predict_bands(*self.layer_compatibilities(proj))
        if self.segment_rules:
            self.labels_ = labels = self.reject_segments(
                labels, proj.latent_time, proj.errors, reversed_errors=proj.reversed_errors
            )
        return labels

    def fit_predict_bands(self, band: np.ndarray, diag: np.ndarray) -> np.ndarray:
        """Segment with given layer compatibilities (:meth:`with_background` adds the background):
        the lowest-energy of ``restarts`` runs, over stretches of ``run_length``; returns layer
        indices (−1 = background)."""
        solver = self._solver()
        stretches = run_stretches(band.shape[1], self.run_length, self.run_margin)
        results = [self._best_run(band[:, lo:hi], diag) for lo, hi, _, _ in stretches]
        self._store(results[0] if len(results) == 1 else _joined(results, stretches, band, diag, solver.J))
        return self.labels_

    def _best_run(self, band: np.ndarray, diag: np.ndarray) -> CLMResult:
        solver = self._solver()
        lam = solver.spectral_scale(band, diag)
        best = None
        for _ in range(int(self.restarts)):
            result = solver.solve(band, diag, lambda_max=lam)
            if best is None or result.energy < best.energy:
                best = result
        return best

    def _store(self, result: CLMResult) -> None:
        self.result_ = result
        self.labels_ = self.labels_from(result)
        self.n_sweeps_ = result.sweeps
        self.energy_ = result.energy
        self.converged_ = result.converged
        self.activities_ = result.activities

    def fit(self, sequence: np.ndarray, y=None) -> CLMSegmenter:
        """Segment a (N, d) sequence and keep the results (``labels_`` …); returns self."""
        self.fit_predict(sequence)
        return self

    def fit_predict(self, sequence: np.ndarray) -> np.ndarray:
        """Segment a (N, d) sequence: class index per observation, −1 = background/unknown."""
        return self.fit_predict_projected(self.candidates.project(sequence))
