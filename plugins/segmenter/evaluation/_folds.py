"""The fold runner of the leave-one-recording-out protocol (docs/segmentation.md, ``--jobs``):
folds one after the other or over forked worker processes with one BLAS thread each (the same
figures either way), finished folds kept in and taken from ``checkpoints``, the progress line
per fold with its estimate of the time left, and each fold's wall time per method and phase."""

from __future__ import annotations

import multiprocessing
import os
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from threadpoolctl import threadpool_limits

from ._checkpoints import FoldCheckpoints, settings_digest
from ._enrolment import fold_note
from ._third_party import counted_warnings

if TYPE_CHECKING:
    from ._recordings import RecordingsEvaluator


def default_jobs() -> int:
    """The number of cores this process may run on (the default of ``--jobs``)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


_FORKED: RecordingsEvaluator | None = None  # the evaluator whose folds the forked workers run


def _one_thread() -> None:
    """A worker's start: its BLAS/OpenMP pools get one thread, so ``jobs`` workers use ``jobs`` cores."""
    threadpool_limits(1)


def _forked_fold(k: int, held: str) -> FoldResult:
    return _FORKED._announced_fold(k, held)


@dataclass
class FoldResult:
    recording: str
    truth: np.ndarray
    labels: dict[str, np.ndarray]
    selected: dict[str, dict]
    sweeps: dict[str, list[np.ndarray]]  # per method: labels at every rejection value of its sweep
    strict: dict[str, np.ndarray]  # per method that fell back: the labels at the strict choice
    untrained: list[str]  # known classes without a training segment in this fold
    unlagged: dict[str, np.ndarray]  # per method: the labels at lag 0 (``labels`` are at the evaluation's lag)
    enrolled: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)  # per adaptation, method: labels
    scored_from: int = 0  # the first frame after the enrolment
    seconds: float = 0.0  # the fold's own wall time
    timing: dict[str, dict[str, float]] = field(default_factory=dict)  # method → phase → seconds
    warnings: dict[str, int] = field(default_factory=dict)  # third-party warnings in the fold: gist → count


def timing(folds: list[FoldResult]) -> dict:
    """Seconds per method and phase (selection, final fit, labelling), summed over the folds, and
    each fold's wall time: the JSON's ``timing`` (on the machine of the run, unlike the figures)."""
    per_method: dict[str, dict[str, float]] = {}
    for fold in folds:
        for name, phases in fold.timing.items():
            for phase, seconds in phases.items():
                per_method.setdefault(name, {}).setdefault(phase, 0.0)
                per_method[name][phase] += seconds
    return {
        "methods": {n: {p: round(v, 2) for p, v in phases.items()} for n, phases in per_method.items()},
        "folds": {f.recording: round(f.seconds, 2) for f in folds},
    }


class FoldRunner:
    """The fold-running part of :class:`._recordings.RecordingsEvaluator`."""

    @contextmanager
    def _timed(self, name: str, phase: str):
        """Adds the wall time of the block to ``name``'s ``phase`` in this fold's timing."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            phases = self._timing.setdefault(name, {})
            phases[phase] = phases.get(phase, 0.0) + time.perf_counter() - t0

    def _announced_fold(self, k: int, held: str) -> FoldResult:
        self.progress(f"fold {k + 1}/{len(self.data.recordings)}: holding out '{held}'")
        t0, caught = time.perf_counter(), Counter()
        with counted_warnings(caught):
            fold = self.run_fold(held)
        fold = replace(fold, seconds=time.perf_counter() - t0, warnings=dict(caught))
        if self.enroll:
            self.progress(f"  {fold_note(fold, self.known)}")
        return fold

    def _run_folds(self) -> list[FoldResult]:
        """Every fold's result in recording order: one after the other, or over ``jobs`` forked
        processes (module docstring); progress per fold either way."""
        global _FORKED
        names, start, done = self.data.names(), time.perf_counter(), {}
        kept = self._checkpoints()
        for held in names if kept else ():
            if (fold := kept.load(held)) is not None:
                done[held] = fold
                self.progress(f"fold '{held}' taken from {kept.path(held)}")
        todo = [(k, held) for k, held in enumerate(names) if held not in done]

        def finished(held: str, fold: FoldResult) -> None:
            done[held] = fold
            computed.append(fold.seconds)
            if kept:
                kept.save(fold)
            spent, left = time.perf_counter() - start, len(names) - len(done)
            if left:  # folds differ in size: their mean so far, over the workers, is the estimate
                self.progress(
                    f"fold '{held}' done ({len(done)}/{len(names)}); {spent / 60:.1f} min so far, "
                    f"about {np.mean(computed) * left / min(jobs, left) / 60:.0f} min to go"
                )

        computed: list[float] = []  # wall times of the folds computed in this run
        jobs = min(self.jobs, len(todo))
        if jobs <= 1:
            with threadpool_limits(1):  # as in a worker: BLAS sums in the same order whatever ``jobs``
                for k, held in todo:
                    finished(held, self._announced_fold(k, held))
            return [done[h] for h in names]
        _FORKED = self
        try:
            context = multiprocessing.get_context("fork")
            with ProcessPoolExecutor(jobs, mp_context=context, initializer=_one_thread) as pool:
                futures = {pool.submit(_forked_fold, k, held): held for k, held in todo}
                try:
                    for future in as_completed(futures):
                        finished(futures[future], future.result())
                finally:  # a fold failed: the folds not yet started are not run
                    pool.shutdown(cancel_futures=True)
        finally:
            _FORKED = None
        return [done[h] for h in names]

    def _checkpoints(self) -> FoldCheckpoints | None:
        """The store of finished folds (``checkpoints``), keyed by the data and every setting that
        moves a figure; None without one."""
        if not self.checkpoints:
            return None
        settings = {k: v for k, v in self._parameters().items() if k != "dataset"}
        settings.update(methods=list(self.methods), random_state=self.random_state)
        digest = settings_digest(self.data.recordings, self.data.class_names, settings)
        return FoldCheckpoints(self.checkpoints, digest, FoldResult, self.progress)
