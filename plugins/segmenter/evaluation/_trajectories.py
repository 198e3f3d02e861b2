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

import multiprocessing
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
from threadpoolctl import threadpool_limits

from ..clm import ETA, CLMSegmenter, default_solver
from ..datasets import LabelledDataset, Trajectory
from ..models import CandidateSet, Projection
from ..scorers import PerClassHMM, SlidingDTW1NN
from ._methods import REGISTRY, TRAJECTORY_METHODS
from ._selection import first_of_best, survivors

EXPERIMENTS = ("single", "concatenated", "middle_halves", "reversed_rejection", "left_out_rejection")
METHODS = TRAJECTORY_METHODS  # the methods of this protocol (the registry's, in its order)
SELECTION_EXPERIMENTS = ("single", "concatenated", "middle_halves")
REJECTION_EXPERIMENTS = ("reversed_rejection", "left_out_rejection")
SELECTIONS = ("open_set", "recognition")
SEGMENT_RULES = ("min_progress", "max_fit_ratio")  # judged after the CLM: its labels are shared
SCREEN_ETA = ETA  # the screen's CLM annealing factor: every candidate set's runs anneal as fast as
# those without heading channels (the slower η of headed ones costs ~3× the sweeps; the screen
# only has to keep the best third, the refinement and the test run the segmenter's own solver)
STRONG_BACKGROUND = 3.0  # docs/segmentation.md: a "strong" background is 3 λ_bg (λ_bg = 1 − 10/N)


@dataclass
class TrajectoryProtocol:
    """Which sub-samplings, histories, CLM runs and pairs to evaluate."""

    nths: tuple[int, ...] = (1, 2, 3, 4)
    histories: tuple[int, ...] = (5, 10, 15, 20)
    runs: int = 4
    max_pairs: int | None = None
    grid_size: int | None = None  # keep only the first grid points per method (quick runs)
    selection: str = "open_set"  # or "recognition" (the thesis): see the module docstring
    heading_folds: int | None = None  # at most this many cross-fitted splits for the heading channels (None: all)

    def __post_init__(self) -> None:
        if self.selection not in SELECTIONS:
            raise ValueError(f"selection must be one of {SELECTIONS}, got {self.selection!r}")

    @classmethod
    def quick(cls) -> TrajectoryProtocol:
        """The reduced protocol for CI and tests."""
        return cls(nths=(1, 2), histories=(10,), runs=2, max_pairs=6, grid_size=8)


def heading_choices(n_channels: int) -> tuple[tuple[int, ...], ...]:
    """The heading channels validation chooses among when ``--headings`` is not given
    (docs/segmentation.md, heading channels), in the order of preference a tie keeps: the first
    two channels — a pen's position x, y in the layouts of docs/segmentation.md — when there are
    at least two, then none.  Documented preference: a heading does not depend on the size or
    place of the motion, which vary between writers and sessions more than a validation split
    shows, so within the noise the view that is invariant to them wins."""
    return ((0, 1), ()) if n_channels >= 2 else ((),)


@dataclass
class Case:
    """One evaluation: ``parts`` = (trajectory index, row indices); ``truth`` per point (−1 = reject)."""

    experiment: str
    name: str
    nth: int
    history: int
    parts: list[tuple[int, np.ndarray]]
    truth: np.ndarray
    left_out: str | None = None
    draw: int = 0  # the same for the cases that differ only in H: seeds the CLM (shared when its span is)

    @property
    def key(self) -> tuple:
        return tuple((i, idx.tobytes()) for i, idx in self.parts)


def _pairs(trajs: list[Trajectory], max_pairs: int | None) -> list[tuple[int, int]]:
    order = sorted(range(len(trajs)), key=lambda i: (trajs[i].label, trajs[i].name))
    pairs = []
    for pos, i in enumerate(order):
        for step in range(1, len(order)):
            j = order[(pos + step) % len(order)]
            if trajs[j].label != trajs[i].label:
                pairs.append((i, j))
                break
    return pairs[:max_pairs] if max_pairs else pairs


def build_cases(trajs: list[Trajectory], classes: list[str], protocol: TrajectoryProtocol) -> list[Case]:
    """All cases of the protocol over one split's trajectories."""
    cls_index = {c: k for k, c in enumerate(classes)}
    cases: list[Case] = []
    pairs = _pairs(trajs, protocol.max_pairs)

    def sub(i: int, nth: int, middle: bool = False) -> np.ndarray:
        n = len(trajs[i].data)
        lo, hi = (n // 4, n // 4 + n // 2) if middle else (0, n)
        return np.arange(lo, hi, nth)

    for n_nth, nth in enumerate(protocol.nths):
        for H in protocol.histories:
            first = len(cases)
            for i, t in enumerate(trajs):
                idx = sub(i, nth)
                truth = np.full(len(idx), cls_index[t.label])
                cases.append(Case("single", t.name, nth, H, [(i, idx)], truth))
                cases.append(Case("reversed_rejection", t.name, nth, H, [(i, idx[::-1].copy())], np.full(len(idx), -1)))
                if len(classes) > 1:
                    cases.append(
                        Case("left_out_rejection", t.name, nth, H, [(i, idx)], np.full(len(idx), -1), left_out=t.label)
                    )
            for experiment, middle in (("concatenated", False), ("middle_halves", True)):
                for i, j in pairs:
                    parts = [(i, sub(i, nth, middle)), (j, sub(j, nth, middle))]
                    truth = np.concatenate(
                        [
                            np.full(len(parts[0][1]), cls_index[trajs[i].label]),
                            np.full(len(parts[1][1]), cls_index[trajs[j].label]),
                        ]
                    )
                    cases.append(Case(experiment, f"{trajs[i].name}+{trajs[j].name}", nth, H, parts, truth))
            for k, case in enumerate(cases[first:]):
                case.draw = n_nth * (len(cases) - first) + k
    return cases


def summarise(correct: list[float]) -> dict:
    c = np.asarray(correct, dtype=float)
    if c.size == 0:
        return {"share_ge_85": None, "share_perfect": None, "mean_correct": None}
    return {
        "share_ge_85": float(np.mean(c >= 0.85)),
        "share_perfect": float(np.mean(c >= 1.0)),
        "mean_correct": float(np.mean(c)),
    }


_FORKED: Evaluator | None = None  # the evaluator whose work the forked processes do
_LOADED: set[str] = set()  # methods whose compiled kernels this process has loaded (before forking)


def _one_thread() -> None:
    """A worker's start: one BLAS/OpenMP thread, so ``jobs`` workers use ``jobs`` cores."""
    threadpool_limits(1)


def _forked_call(name: str, item: tuple):
    _FORKED.jobs = 1  # a worker does its share itself
    return getattr(_FORKED, name)(*item)


def screen_pairs(protocol: TrajectoryProtocol) -> set[tuple[int, int]]:
    """The (N^th, H) pairs of the *screen* (docs/segmentation.md, "How the trajectory protocol
    chooses"): the diagonal of the N^th × H design — the k-th sub-sampling with the k-th history,
    cycling the shorter list — so every N^th and every H is screened, a quarter of the cases of
    the full protocol."""
    nths, hs = protocol.nths, protocol.histories
    return {(nths[k % len(nths)], hs[k % len(hs)]) for k in range(max(len(nths), len(hs)))}


def cross_fitted_splits(dataset: LabelledDataset, folds: int | None = None) -> list[LabelledDataset]:
    """The splits the heading channels are chosen on (docs/segmentation.md): per class the
    *pool* is its training then its validation trajectories (split order); fold ``f`` validates
    the ``f``-th block of ``n_val`` (the class's validation count) from the pool's end and trains
    on the rest, so fold 0 is ``dataset`` itself and every fold trains on as many trajectories
    as the train split.  ``K = min over classes of len(pool) // n_val`` folds (at most
    ``folds``): with 3 train / 1 validation letters per class every one of the 4 is validated
    once.  The test split is never touched."""
    pools: dict[str, list[Trajectory]] = {}
    n_val: dict[str, int] = {}
    for t in dataset.train + dataset.validation:
        pools.setdefault(t.label, []).append(t)
    for t in dataset.validation:
        n_val[t.label] = n_val.get(t.label, 0) + 1
    if not n_val:
        return [dataset]
    k = min(len(pools[c]) // n for c, n in n_val.items())
    k = max(1, min(k, folds) if folds else k)
    out = [dataset]
    for f in range(1, k):
        train, validation = [], []
        for c, pool in pools.items():
            n = n_val.get(c, 0)
            held = set(range(len(pool) - (f + 1) * n, len(pool) - f * n)) if n else set()
            for j, t in enumerate(pool):
                (validation if j in held else train).append(t)
        out.append(replace(dataset, train=train, validation=validation))
    return out


@dataclass
class Evaluator:
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

    # -- data of a case ---------------------------------------------------------------------
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

    # -- methods (the registry's, docs/segmentation.md) -------------------------------------
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

    def objective(self, res: dict) -> float:
        """The validation score of one grid point's results (``TrajectoryProtocol.selection``)."""

        def mean_of(experiments: tuple[str, ...]) -> float | None:
            shares = [res[e]["mean_correct"] for e in experiments if res.get(e, {}).get("mean_correct") is not None]
            return float(np.mean(shares)) if shares else None

        recognition, rejection = mean_of(SELECTION_EXPERIMENTS), mean_of(REJECTION_EXPERIMENTS)
        if self.protocol.selection == "recognition" or rejection is None:
            return recognition
        return 0.5 * (recognition + rejection)

    def validation_objective(self, method: str, params: dict, screen: bool = False, cheap: bool | None = None) -> float:
        """:meth:`objective` of one grid point on the validation split (one CLM run per case),
        on the screen's cases or on all, ``cheap`` (default: ``screen``) with the screen's CLM
        annealing (:data:`SCREEN_ETA`); computed once."""
        key = self._objective_key(method, params, screen, cheap)
        if key not in self._objectives:
            res = self.run(method, params, "validation", screen=screen, cheap=cheap)
            self._objectives[key] = self.objective(res)
        return self._objectives[key]

    @staticmethod
    def _objective_key(method: str, params: dict, screen: bool, cheap: bool | None = None) -> tuple:
        return (method, repr(sorted(params.items())), bool(screen), bool(screen if cheap is None else cheap))

    @property
    def screens(self) -> bool:
        """Whether the screen is a proper part of the validation cases (else every candidate is
        scored on all of them at once)."""
        return any((c.nth, c.history) not in self.screen for c in self.cases["validation"])

    def select(self, method: str) -> tuple[dict, float]:
        """The grid point chosen on validation by successive halving: (params, objective).  The
        unit of the halving is a *run*: the grid points that differ only in the segment rules
        judged after the CLM (:data:`SEGMENT_RULES`) share one, so they are screened and refined
        together, a run scoring its best rule.  Every run is *screened* on the cases of
        :func:`screen_pairs`; the best third (:func:`._selection.survivors`) is *refined* on all
        validation cases; among the refined grid points the first within ``TIE_MARGIN`` of the
        best objective wins (:func:`._selection.first_of_best`, grid order)."""
        if self.jobs > 1:
            self.warm(method, "validation")  # the baselines' thresholds already need their scores
        grid = self.grid(method)
        groups: dict[str, list[int]] = {}
        for i, params in enumerate(grid):
            groups.setdefault(repr(sorted((k, v) for k, v in params.items() if k not in SEGMENT_RULES)), []).append(i)
        runs = list(groups.values())
        kept = runs
        if self.screens and len(runs) > 1:
            screened = self.objectives(method, [[grid[i] for i in run] for run in runs], screen=True)
            kept = [runs[k] for k in survivors([max(scores) for scores in screened])]
        keep = sorted(i for run in kept for i in run)
        by_run = self.objectives(method, [[grid[i] for i in run] for run in kept])
        refined_of = {i: score for run, scores in zip(kept, by_run) for i, score in zip(run, scores)}
        refined = [refined_of[i] for i in keep]
        for i, score in zip(keep, refined):
            self.progress(f"  {method} validation {grid[i]}: {score:.3f}")
        best = first_of_best(refined)
        self._halving = {"candidates": len(grid), "runs": len(runs), "refined_runs": len(kept), "refined": len(keep)}
        return grid[keep[best]], refined[best]

    def objectives(self, method: str, runs: list[list[dict]], screen: bool = False) -> list[list[float]]:
        """:meth:`validation_objective` of every grid point of every run (lists of grid points
        sharing one run), the runs over ``jobs`` forked processes."""
        todo = [run for run in runs if any(self._objective_key(method, p, screen) not in self._objectives for p in run)]
        if todo and self.jobs > 1:
            self.warm(method, "validation")
            for run, scores in zip(todo, self._parallel("_run_objectives", [(method, run, screen) for run in todo])):
                for params, score in zip(run, scores):
                    self._objectives[self._objective_key(method, params, screen)] = score
        return [self._run_objectives(method, run, screen) for run in runs]

    def _run_objectives(self, method: str, run: list[dict], screen: bool) -> list[float]:
        return [self.validation_objective(method, params, screen=screen) for params in run]

    def _fold(self, k: int) -> Evaluator:
        """This evaluator on the ``k``-th split of :func:`cross_fitted_splits` (0: itself), its
        heading channels' candidates retrained by ``trainer`` on that split's train part."""
        if k == 0:
            return self
        if k not in self._fold_cache:
            ds = cross_fitted_splits(self.dataset, self.protocol.heading_folds)[k]
            cands = self.trainer(ds, tuple(self.headings))
            self._fold_cache[k] = replace(self, dataset=ds, candidates=cands, alternatives=(), trainer=None, jobs=1)
        return self._fold_cache[k]

    def n_folds(self) -> int:
        """How many cross-fitted splits the heading channels are chosen on (1 without a ``trainer``)."""
        return len(cross_fitted_splits(self.dataset, self.protocol.heading_folds)) if self.trainer else 1

    def _fold_objectives(self, h: int, k: int, tasks: list[tuple[str, dict]]) -> list[float]:
        """The objective on the screen's cases (at full fidelity: the segmenter's own annealing)
        of every (method, params) of ``tasks`` on fold ``k`` with the ``h``-th candidate set's
        heading channels."""
        fold = [self, *self._others][h]._fold(k)
        return [fold.validation_objective(method, params, screen=True, cheap=False) for method, params in tasks]

    def cross_fit(self, tasks: list[list[tuple[str, dict]]]) -> list[list[list[float]]]:
        """Per candidate set ``h`` and (method, params) of ``tasks[h]``: the screen objective on
        every cross-fitted split (:meth:`_fold`), each fold trained once for all methods; the
        (candidate set, fold) pairs over ``jobs`` forked processes."""
        items = [(h, k, tasks[h]) for k in range(1, self.n_folds()) for h in range(len(tasks))]
        if items:
            self.progress(
                f"heading channels: training and scoring {len(items)} cross-fitted split(s) "
                f"({self.n_folds() - 1} fold(s) × {len(tasks)} candidate sets)"
            )
        done = dict(zip([(h, k) for h, k, _ in items], self._parallel("_fold_objectives", items)))
        return [
            [
                [self._fold_objectives(h, 0, [task])[0]] + [done[h, k][n] for k in range(1, self.n_folds())]
                for n, task in enumerate(tasks[h])
            ]
            for h in range(len(tasks))
        ]

    def choose(self, method: str) -> tuple[Evaluator, dict, float]:
        """:meth:`choose_all` of one method."""
        return self.choose_all((method,))[method]

    def choose_all(self, methods: tuple[str, ...]) -> dict[str, tuple[Evaluator, dict, float]]:
        """Per method the evaluator (heading channels) and grid point: (evaluator, params,
        validation objective).  Each candidate set's grid point is chosen by :meth:`select`; a
        manifold method then chooses among the candidate sets (heading channels) — a choice that
        decides much — by the mean of that grid point's screen objective over the cross-fitted
        splits (:meth:`cross_fit`; the validation objective without a ``trainer``), the first
        within ``TIE_MARGIN`` of the best in candidate order (:func:`heading_choices`: heading channels first)."""
        evaluators = [self, *self._others]
        picks: dict[str, list[tuple[dict, float]]] = {}
        for method in methods:
            t0 = time.perf_counter()
            self.progress(f"{method}: selecting parameters on validation")
            evs = evaluators if REGISTRY[method].manifolds else [self]
            picks[method], halving = [], []
            for ev in evs:
                if len(evs) > 1:
                    self.progress(f"{method}: heading channels {ev.headings or 'none'}")
                picks[method].append(ev.select(method))
                halving.append(ev._halving)
            self.choices[method] = {"halving": halving[0] if len(evs) == 1 else halving}
            self.timing[method] = {"selection": round(time.perf_counter() - t0, 2)}
        manifold = [m for m in methods if len(picks[m]) > 1]
        folds: dict[str, list[list[float]]] = {}
        if manifold:
            t0 = time.perf_counter()
            if self.n_folds() > 1:
                scores = self.cross_fit([[(m, picks[m][h][0]) for m in manifold] for h in range(len(evaluators))])
                folds = {m: [scores[h][n] for h in range(len(evaluators))] for n, m in enumerate(manifold)}
            self.timing["heading_folds"] = round(time.perf_counter() - t0, 2)
        out = {}
        for method in methods:
            k = 0
            if method in manifold:
                f = folds.get(method) or [[score] for _, score in picks[method]]
                pooled = [float(np.mean(x)) for x in f]
                k = first_of_best(pooled)
                self.choices[method]["headings"] = [
                    {"channels": ev.headings, "params": params, "validation": score, "folds": x, "pooled": p}
                    for ev, (params, score), x, p in zip(evaluators, picks[method], f, pooled)
                ]
                self.progress(
                    f"{method}: validation chose heading channels {evaluators[k].headings or 'none'} "
                    f"({pooled[k]:.3f} over {len(f[k])} split(s); "
                    + ", ".join(f"{ev.headings or 'none'}: {p:.3f}" for ev, p in zip(evaluators, pooled))
                    + ")"
                )
            ev = evaluators[k] if method in manifold else self
            self.chosen[method] = ev
            out[method] = (ev, *picks[method][k])
        return out

    # -- processes ----------------------------------------------------------------------------
    def _parallel(self, name: str, items: list[tuple]) -> list:
        """``self.<name>(*item)`` for every item, over ``jobs`` forked processes (each with one
        BLAS thread), in item order; one after the other with ``jobs`` 1."""
        global _FORKED
        jobs = min(self.jobs, len(items))
        if jobs <= 1:
            return [getattr(self, name)(*item) for item in items]
        _FORKED = self
        try:
            context = multiprocessing.get_context("fork")
            with ProcessPoolExecutor(jobs, mp_context=context, initializer=_one_thread) as pool:
                return list(pool.map(_forked_call, [name] * len(items), items))
        finally:
            _FORKED = None

    def warm(self, method: str, split: str) -> None:
        """Before forking: what every process of ``method`` on ``split`` needs and would
        otherwise compute again — the cases' projections (manifold methods) or baseline scores —
        computed over ``jobs`` processes and kept here."""
        entry = REGISTRY[method]
        if method not in _LOADED:  # the compiled kernels, loaded here once instead of in every worker
            self.predict(method, {}, split, min(self.cases[split], key=lambda c: c.truth.size))
            _LOADED.add(method)
        if entry.manifolds:
            todo = sorted(
                {self._projection_key(split, i, idx): (i, idx) for c in self.cases[split] for i, idx in c.parts}.items()
            )
            todo = [(key, i, idx) for key, (i, idx) in todo if key not in self._projections]
            for (key, _, _), proj in zip(todo, self._parallel("_projected", [(split, i, idx) for _, i, idx in todo])):
                self._projections[key] = proj
        elif hasattr(entry, "trajectory_model"):
            entry.trajectory_model(self)  # fitted once, here
            groups = self._case_groups(split)
            for found in self._parallel("_scored", [(method, split, g) for g in groups]):
                self._scores.update(found)

    def _projection_key(self, split: str, i: int, idx: np.ndarray) -> tuple:
        return (split, i) if not self.candidates.stateful else (split, i, idx.tobytes())

    def _projected(self, split: str, i: int, idx: np.ndarray) -> Projection:
        self._projection(split, i, idx)
        return self._projections[self._projection_key(split, i, idx)]

    def _scored(self, method: str, split: str, group: list[int]) -> dict:
        before = set(self._scores)
        for n in group:
            self.baseline_scores(method, split, self.cases[split][n])
        return {k: v for k, v in self._scores.items() if k not in before}

    def _case_groups(self, split: str) -> list[list[int]]:
        """The split's case indices grouped by trajectory (the cases of one group share projections,
        scores and CLM runs), in order of first appearance."""
        groups: dict[int, list[int]] = {}
        for n, case in enumerate(self.cases[split]):
            groups.setdefault(case.parts[0][0], []).append(n)
        return list(groups.values())

    def evaluate(self, methods: tuple[str, ...] = METHODS) -> dict:
        """Select on validation, report on test: the JSON structure of ``evaluate segmentation``."""
        out: dict = {
            "methods": {},
            "parameters": {
                "protocol": {
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
