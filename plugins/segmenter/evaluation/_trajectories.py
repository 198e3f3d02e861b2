"""The thesis evaluation protocol (docs/segmentation.md §D) for all four methods.

Experiments (``EXPERIMENTS``), each built from the trajectories of one split:

* ``single`` — every whole trajectory;
* ``concatenated`` — pairs of whole trajectories of different classes, one after the other;
* ``middle_halves`` — the same pairs, each cut to its middle half (``n//4 … n//4 + n//2``);
* ``reversed_rejection`` — every trajectory reversed: every point must be rejected;
* ``left_out_rejection`` — every trajectory with its own class removed from the model set:
  every point must be rejected.

Each case is run for every sub-sampling ``N^th`` and every history/neighbourhood ``H`` of the
:class:`TrajectoryProtocol`; the metric is the share of correctly labelled points (rejection = −1).
Pairs: trajectory ``i`` (sorted by label, then name) is followed by the next trajectory in that
order with a different label (documented deterministic choice), at most ``max_pairs`` pairs.

Parameter selection: every method has a small grid (:meth:`Evaluator.grid`), searched by
successive halving on the validation split (:meth:`Evaluator.select`, docs/segmentation.md "How the
trajectory protocol chooses"): grid points sharing one CLM run (they differ only in the segment
rules) are screened together on the cases of :func:`screen_pairs` (one CLM run per case, annealed
at :data:`SCREEN_ETA`), the best third of the runs (``_selection.survivors``) is refined on all
validation cases, and the first grid point within ``TIE_MARGIN`` of the best wins
(``_selection.first_of_best``).  ``TrajectoryProtocol.selection``:
``"open_set"`` (default) scores the mean of two figures, the mean share correct over the
*recognition* experiments (``SELECTION_EXPERIMENTS``) and over the *rejection* experiments
(``REJECTION_EXPERIMENTS``), so the selected operating point has to keep known motions and reject
unknown ones; ``"recognition"`` scores the recognition experiments only, as in the thesis (the
background / rejection threshold is tuned to keep the validation motions).  The manifold methods
also choose among the ``alternatives`` — candidate sets trained with other heading channels
(:func:`heading_choices`, in their order of preference) — by the mean objective of each set's
chosen grid point over the cross-fitted splits of :func:`cross_fitted_splits` (every train and
validation trajectory validated once), the first within ``TIE_MARGIN`` of the best.  The best is
evaluated on the test split
(the CLM with ``runs`` runs per case: a case's share is the mean over runs, its ``std`` the
standard deviation); the UKR/CLM rejection experiments are also reported with a *strong*
background (``3 λ_bg`` with the thesis rule ``λ_bg = 1 − 10/N``, docs/segmentation.md) under
``strong_background``.  Summary per
experiment: ``share_ge_85`` (cases with ≥ 85 % correct), ``share_perfect`` (100 % correct),
``mean_correct`` — all fractions in [0, 1].
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
from threadpoolctl import threadpool_limits

from ..clm import CLMSegmenter, default_solver
from ..datasets import LabelledDataset
from ..models import CandidateSet, Projection
from ..scorers import PerClassHMM, SlidingDTW1NN
from ._methods import REGISTRY
from ._protocols import protocol
from ._trajectory_cases import (
    EXPERIMENTS,
    METHODS,
    REJECTION_EXPERIMENTS,
    SCREEN_ETA,
    SEGMENT_RULES,
    STRONG_BACKGROUND,
    Case,
    TrajectoryProtocol,
    build_cases,
    screen_pairs,
    summarise,
)
from ._trajectory_selection import TrajectorySelection
from ._trajectory_work import ForkedWork


@dataclass
class Evaluator(TrajectorySelection, ForkedWork):
    """Runs the protocol for the four methods on one dataset with trained candidates; the manifold
    methods choose among ``candidates`` and the ``alternatives`` (other heading channels,
    :func:`heading_choices`) on the cross-fitted splits of :func:`cross_fitted_splits` when a
    ``trainer`` (dataset, heading channels → candidates trained on its train split) is given,
    else on the validation split alone."""

    dataset: LabelledDataset
    candidates: CandidateSet
    protocol: TrajectoryProtocol = field(default_factory=TrajectoryProtocol)
    random_state: int = 0
    progress: Callable[[str], None] = lambda msg: None
    alternatives: tuple[CandidateSet, ...] = ()
    trainer: Callable[[LabelledDataset, tuple[int, ...]], CandidateSet] | None = None
    jobs: int = 1  # forked processes (docs/segmentation.md, ``--jobs``): the same figures with any number
    preview: bool = False  # choose on the test cases that are reported (the preview protocol) instead of validation

    def __post_init__(self) -> None:
        self.classes = self.candidates.classes
        missing = sorted(set(self.dataset.classes) - set(self.classes))
        if missing:
            raise ValueError(f"no trained model for classes {missing}; retrain the models on this dataset")
        self._projections: dict[tuple, Projection] = {}
        self._scores: dict[tuple, np.ndarray] = {}
        self._labels: dict[tuple, np.ndarray] = {}
        self._candidate_layers: dict[tuple, tuple[np.ndarray, float]] = {}
        self._screening = False  # whether the cases run now are the screen's (:data:`SCREEN_ETA`)
        self._objectives: dict[tuple, float] = {}
        self._fold_cache: dict[int, Evaluator] = {}
        self.timing: dict = {}  # seconds per method and phase (the JSON's parameters.timing_s)
        self.cases = {
            split: build_cases(self.dataset.split(split), self.classes, self.protocol)
            for split in ("validation", "test")
        }
        self.screen = screen_pairs(self.protocol)
        self.chosen: dict[str, Evaluator] = {}  # method → the evaluator of its chosen candidates
        self.choices: dict[str, dict] = {}  # method → how it was chosen (the JSON's parameters.selection)
        self._others = [replace(self, candidates=c, alternatives=()) for c in self.alternatives]

    @property
    def headings(self) -> list[int]:
        """The heading channels of this evaluator's candidates."""
        return list(self.candidates.headings.channels)

    @cached_property
    def dtw(self) -> SlidingDTW1NN:
        self.progress("fitting the DTW baseline's references")
        return SlidingDTW1NN().fit(dict(self.dataset.by_class("train").items()))

    @cached_property
    def hmm(self) -> PerClassHMM:
        self.progress("fitting the per-class HMMs")
        return PerClassHMM(random_state=self.random_state).fit(dict(self.dataset.by_class("train").items()))

    def _projection(self, split: str, i: int, idx: np.ndarray) -> Projection:
        """Projection of the observations ``idx`` of trajectory ``i``: rows of the whole trajectory's
        for pointwise candidates, else (heading channels, delay embedding) of those observations
        as a sequence of their own — sub-sampled, cut or reversed as a stream would bring them."""
        data = self.dataset.split(split)[i].data
        pointwise = not self.candidates.stateful
        key = (split, i) if pointwise else (split, i, idx.tobytes())
        if key not in self._projections:
            self._projections[key] = self.candidates.project(data if pointwise else data[idx])
        return self._projections[key].take(idx) if pointwise else self._projections[key]

    def projection(self, split: str, case: Case) -> Projection:
        proj = Projection.concatenate([self._projection(split, i, idx) for i, idx in case.parts])
        return proj.without(case.left_out) if case.left_out else proj

    def sequence(self, split: str, case: Case) -> np.ndarray:
        trajs = self.dataset.split(split)
        return np.vstack([trajs[i].data[idx] for i, idx in case.parts])

    def case_candidates(self, case: Case) -> CandidateSet:
        """The candidates a case is recognised with (without its left-out class)."""
        return self.candidates.without(case.left_out) if case.left_out else self.candidates

    def to_global(self, labels: np.ndarray, names: list[str]) -> np.ndarray:
        lut = np.array([self.classes.index(n) for n in names] + [-1])
        return lut[np.where(labels < 0, len(names), labels)]

    def grid(self, method: str, split: str = "validation") -> list[dict]:
        """The parameter grid of a method (documented, small; thresholds are data-derived)."""
        g = REGISTRY[method].trajectory_grid(self, split)
        return g[: self.protocol.grid_size] if self.protocol.grid_size else g

    def baseline_thresholds(self, method: str, split: str) -> list[float | None]:
        """None plus the 5 % and 25 % quantiles of the winning score on the split's single cases."""
        best = np.concatenate(
            [self.baseline_scores(method, split, c).max(axis=1) for c in self.cases[split] if c.experiment == "single"]
        )
        return [None, float(np.quantile(best, 0.25)), float(np.quantile(best, 0.05))]

    def baseline_scores(self, method: str, split: str, case: Case) -> np.ndarray:
        """The baseline's (N, M) scores of a case.  Its scores are those of the causal window of
        ``H`` observations ending at each point, so a case's parts are scored once each (a
        trajectory's own scores serve its single, left-out and concatenated cases) and only the
        first ``H − 1`` points of a later part, whose windows reach back into the part before, are
        scored again with that context."""
        key = (method, split, case.key, case.history)
        if key not in self._scores:
            self._scores[key] = self._joined_scores(method, split, case.parts, case.history)
        return self._scores[key]

    def _joined_scores(self, method: str, split: str, parts: list[tuple[int, np.ndarray]], H: int) -> np.ndarray:
        model = REGISTRY[method].trajectory_model(self)
        model.window = H
        trajs = self.dataset.split(split)
        out, before = [], []
        for i, idx in parts:
            data = trajs[i].data[idx]
            key = (method, split, ((i, idx.tobytes()),), H)
            if key not in self._scores:
                self._scores[key] = model.scores(data)
            own = self._scores[key]
            if before and H > 1:
                context = np.vstack(before)[-(H - 1) :]
                head = min(H - 1, len(data))
                own = np.vstack([model.scores(np.vstack([context, data[:head]]))[len(context) :], own[head:]])
            out.append(own)
            before.append(data)
        return np.vstack(out)

    def predict(self, method: str, params: dict, split: str, case: Case, seed: int = 0) -> np.ndarray:
        """Global class index per point of a case (−1 = rejected)."""
        return REGISTRY[method].predict_case(self, params, split, case, seed)

    def clm_labels(
        self, split: str, case: Case, seed: int, cands: CandidateSet, proj: Projection, params: dict
    ) -> np.ndarray:
        """The CLM's labels before the segment rules (:data:`SEGMENT_RULES`, which only reject after
        the CLM): computed once per case, seed and the other parameters; on the screen
        (:meth:`run` with ``screen``) with the cheaper annealing :data:`SCREEN_ETA`.  The CLM sees H only
        through its neighbourhood ``max(H, min_span)``, so the cases that differ only in H (their
        seeds are equal, :attr:`Case.draw`) share one run where that span is the same; the
        candidate layers' bands and largest eigenvalues, which neither the seed nor the background
        changes, are computed once per case, span and error scale (:meth:`_layers`)."""
        clm = {k: v for k, v in params.items() if k not in SEGMENT_RULES}
        span = max(int(case.history), int(clm.pop("min_span", 0)))
        screen = self._screening and set(clm) <= {"background_factor", "error_scale"}
        key = (split, case.left_out, case.key, span, seed, tuple(sorted(clm.items())), screen)
        if key not in self._labels:
            seg = CLMSegmenter(cands, history=span, random_state=seed, **clm)
            if set(clm) <= {"background_factor", "error_scale"}:
                fidelity = {"eta": SCREEN_ETA} if screen else {}  # else the segmenter's own solver
                solver = default_solver(cands, **fidelity).set_params(random_state=seed)
                band, diag, lam = self._layers(split, case, span, seg, solver, proj)
                self._labels[key] = seg.labels_from(solver.solve(band, diag, lambda_max=lam))
            else:
                self._labels[key] = seg.fit_predict_projected(proj)
        return self._labels[key]

    def _layers(
        self, split: str, case: Case, span: int, seg: CLMSegmenter, solver, proj: Projection
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """All layers' bands, diagonals and largest eigenvalue of one CLM problem (the segmenter's
        :meth:`~CLMSegmenter.layer_compatibilities` and its solver's spectral scale), the
        candidate layers' part shared by every background and seed."""
        key = (split, case.left_out, case.key, span, float(seg.error_scale))
        if key not in self._candidate_layers:
            band, diag = seg.layer_compatibilities(proj)
            self._candidate_layers[key] = (band[:-1], solver.spectral_scale(band[:-1], diag[:-1]))
        cand, lam = self._candidate_layers[key]
        band, diag = seg.with_background(cand)
        return band, diag, max(lam, solver.spectral_scale(band[-1:], diag[-1:]))

    def run(
        self,
        method: str,
        params: dict,
        split: str,
        runs: int = 1,
        experiments: tuple[str, ...] = EXPERIMENTS,
        screen: bool = False,
        cheap: bool | None = None,
    ) -> dict:
        """Per-experiment summaries and cases of one method and parameter set on one split
        (``screen``: only the cases of :func:`screen_pairs`)."""
        self._screening = bool(screen if cheap is None else cheap)
        wanted = [
            n
            for n, case in enumerate(self.cases[split])
            if case.experiment in experiments and not (screen and (case.nth, case.history) not in self.screen)
        ]
        if self.jobs > 1:
            self.warm(method, split)
            groups = [[n for n in g if n in set(wanted)] for g in self._case_groups(split)]
            groups = [g for g in groups if g]
            entries = dict(
                pair
                for found in self._parallel("_case_entries", [(method, params, split, runs, g) for g in groups])
                for pair in found
            )
        else:
            entries = dict(self._case_entries(method, params, split, runs, wanted))
        per_exp: dict[str, list[dict]] = {e: [] for e in experiments}
        for n in wanted:
            per_exp[self.cases[split][n].experiment].append(entries[n])
        return {e: dict(summarise([c["correct"] for c in cs]), cases=cs) for e, cs in per_exp.items()}

    def _case_entries(self, method: str, params: dict, split: str, runs: int, indices: list[int]) -> list:
        """(case index, its JSON entry) of the split's cases ``indices``."""
        out = []
        for n in indices:
            case = self.cases[split][n]
            shares = [
                float(
                    np.mean(
                        self.predict(method, params, split, case, seed=self.random_state * 100003 + case.draw * 7 + r)
                        == case.truth
                    )
                )
                for r in range(runs)
            ]
            out.append(
                (
                    n,
                    {
                        "name": case.name,
                        "nth": case.nth,
                        "H": case.history,
                        "n_points": int(case.truth.size),
                        "correct": float(np.mean(shares)),
                        "std": float(np.std(shares)),
                    },
                )
            )
        return out

    def evaluate(self, methods: tuple[str, ...] = METHODS) -> dict:
        """Select on validation, report on test: the JSON structure of ``evaluate segmentation``."""
        out: dict = {
            "protocol": protocol(self.preview, "trajectories"),
            "methods": {},
            "parameters": {
                "protocol": {
                    "choose_on": self.choosing,
                    "nths": list(self.protocol.nths),
                    "histories": list(self.protocol.histories),
                    "runs": self.protocol.runs,
                    "max_pairs": self.protocol.max_pairs,
                    "selection": self.protocol.selection,
                    "screen": sorted(self.screen),
                },
                "classes": self.classes,
                "dataset": self.dataset.source,
                "selected": {},
                "validation_score": {},
                "heading_candidates": [self.headings] + [ev.headings for ev in self._others],
                "heading_channels": {},
                "selection": {},
                "timing_s": {},
            },
        }
        with threadpool_limits(1):  # as in a worker: the same figures whatever ``jobs``
            chosen = self.choose_all(methods)
            for method in methods:
                t0 = time.perf_counter()
                ev, params, score = chosen[method]
                entry = REGISTRY[method]
                runs = self.protocol.runs if entry.repeated_runs else 1
                self.progress(f"{method}: evaluating {params} on test ({runs} run(s) per case)")
                out["methods"][method] = ev.run(method, params, "test", runs=runs)
                if entry.strong_background:
                    strong = dict(params, background_factor=STRONG_BACKGROUND)
                    self.progress(f"{method}: rejection experiments with a strong background {strong}")
                    for exp, res in ev.run(
                        method, strong, "test", runs=runs, experiments=REJECTION_EXPERIMENTS
                    ).items():
                        out["methods"][method][exp]["strong_background"] = res
                    out["parameters"]["strong_background"] = strong
                out["parameters"]["selected"][method] = params
                out["parameters"]["validation_score"][method] = score
                out["parameters"]["selection"][method] = self.choices[method]
                if entry.manifolds:
                    out["parameters"]["heading_channels"][method] = ev.headings
                self.timing[method]["test"] = round(time.perf_counter() - t0, 2)
                self.progress(f"{method}: done ({self.timing[method]})")
        out["parameters"]["timing_s"] = self.timing
        return out
