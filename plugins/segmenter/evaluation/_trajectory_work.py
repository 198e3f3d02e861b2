"""The labelled-trajectory protocol's work over forked processes (docs/segmentation.md,
``--jobs``): projections, baseline scores and CLM runs computed once in the parent or shared out
over ``jobs`` workers with one BLAS thread each, in item order (the same figures either way)."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from threadpoolctl import threadpool_limits

from ..models import Projection
from ._methods import REGISTRY

_FORKED: ForkedWork | None = None  # the evaluator whose work the forked processes do


_LOADED: set[str] = set()  # methods whose compiled kernels this process has loaded (before forking)


def _one_thread() -> None:
    """A worker's start: one BLAS/OpenMP thread, so ``jobs`` workers use ``jobs`` cores."""
    threadpool_limits(1)


def _forked_call(name: str, item: tuple):
    _FORKED.jobs = 1  # a worker does its share itself
    return getattr(_FORKED, name)(*item)


class ForkedWork:
    """The process part of :class:`._trajectories.Evaluator`."""

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
