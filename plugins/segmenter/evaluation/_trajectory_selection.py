"""How the labelled-trajectory protocol chooses (docs/segmentation.md, "How the trajectory
protocol chooses"): successive halving over each method's grid on the validation cases, and the
heading channels over cross-fitted splits of the training and validation trajectories."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from ._methods import REGISTRY
from ._selection import first_of_best, survivors
from ._trajectory_cases import REJECTION_EXPERIMENTS, SEGMENT_RULES, SELECTION_EXPERIMENTS, cross_fitted_splits


class TrajectorySelection:
    """The selection part of :class:`._trajectories.Evaluator`."""

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
            res = self.run(method, params, self.choosing, screen=screen, cheap=cheap)
            self._objectives[key] = self.objective(res)
        return self._objectives[key]

    @staticmethod
    def _objective_key(method: str, params: dict, screen: bool, cheap: bool | None = None) -> tuple:
        return (method, repr(sorted(params.items())), bool(screen), bool(screen if cheap is None else cheap))

    @property
    def choosing(self) -> str:
        """The split the candidates are scored on: validation, or the reported test split in the
        preview (docs/segmentation.md, "Which protocol when")."""
        return "test" if self.preview else "validation"

    @property
    def screens(self) -> bool:
        """Whether the screen is a proper part of the validation cases (else every candidate is
        scored on all of them at once)."""
        return any((c.nth, c.history) not in self.screen for c in self.cases[self.choosing])

    def select(self, method: str) -> tuple[dict, float]:
        """The grid point chosen on validation by successive halving: (params, objective).  The
        unit of the halving is a *run*: the grid points that differ only in the segment rules
        judged after the CLM (:data:`SEGMENT_RULES`) share one, so they are screened and refined
        together, a run scoring its best rule.  Every run is *screened* on the cases of
        :func:`screen_pairs`; the best third (:func:`._selection.survivors`) is *refined* on all
        validation cases; among the refined grid points the first within ``TIE_MARGIN`` of the
        best objective wins (:func:`._selection.first_of_best`, grid order)."""
        if self.jobs > 1:
            self.warm(method, self.choosing)  # the baselines' thresholds already need their scores
        grid = self.grid(method, self.choosing)
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
            self.warm(method, self.choosing)
            for run, scores in zip(todo, self._parallel("_run_objectives", [(method, run, screen) for run in todo])):
                for params, score in zip(run, scores):
                    self._objectives[self._objective_key(method, params, screen)] = score
        return [self._run_objectives(method, run, screen) for run in runs]

    def _run_objectives(self, method: str, run: list[dict], screen: bool) -> list[float]:
        return [self.validation_objective(method, params, screen=screen) for params in run]

    def _fold(self, k: int) -> TrajectorySelection:
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
        if self.preview or not self.trainer:  # the preview scores every candidate set on the test cases once
            return 1
        return len(cross_fitted_splits(self.dataset, self.protocol.heading_folds))

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

    def choose(self, method: str) -> tuple[TrajectorySelection, dict, float]:
        """:meth:`choose_all` of one method."""
        return self.choose_all((method,))[method]

    def choose_all(self, methods: tuple[str, ...]) -> dict[str, tuple[TrajectorySelection, dict, float]]:
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
            self.progress(f"{method}: selecting parameters on {self.choosing}")
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
                    f"{method}: {self.choosing} chose heading channels {evaluators[k].headings or 'none'} "
                    f"({pooled[k]:.3f} over {len(f[k])} split(s); "
                    + ", ".join(f"{ev.headings or 'none'}: {p:.3f}" for ev, p in zip(evaluators, pooled))
                    + ")"
                )
            ev = evaluators[k] if method in manifold else self
            self.chosen[method] = ev
            out[method] = (ev, *picks[method][k])
        return out
