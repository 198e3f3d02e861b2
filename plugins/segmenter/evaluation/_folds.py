"""The fold runner of the leave-one-recording-out protocol (docs/segmentation.md, ``--jobs``):
folds one after the other, over local worker processes (``jobs``, joblib's loky), or on a
dask.distributed cluster (``scheduler``), through joblib and with one BLAS thread each — the
same figures every way; finished folds kept in and taken from ``checkpoints``, each method's
part of a fold in and from ``cache``; the progress line per fold with its estimate of the time
left, and each fold's wall time per method and phase."""

from __future__ import annotations

import os
import time
from collections import Counter
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Protocol

import numpy as np
from joblib import Parallel, delayed, parallel_config
from threadpoolctl import threadpool_limits

from ._checkpoints import UNSAFE, FoldCheckpoints, settings_digest
from ._enrolment import fold_note
from ._fold_result import FoldResult, MethodFold
from ._methods import REGISTRY
from ._third_party import counted_warnings


class FoldTask(Protocol):
    """What a worker needs of the evaluator that travels with a fold's task (the evaluator is
    :class:`._recordings.RecordingsEvaluator`, defined above this module)."""

    def _announced_fold(self, k: int, held: str) -> FoldResult: ...


def default_jobs() -> int:
    """The number of cores this process may run on (the default of ``--jobs``)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _shipped_fold(evaluator: FoldTask, k: int, held: str) -> FoldResult:
    """A fold in a worker process, local or a cluster's, to which the evaluator travels with the
    task (one BLAS thread)."""
    with threadpool_limits(1):
        return evaluator._announced_fold(k, held)


def cluster_client(scheduler: str):
    """A dask.distributed client of the scheduler at ``scheduler`` (``tcp://HOST:PORT``); an
    ImportError that says what to install, a ValueError when no scheduler answers there."""
    try:
        from dask.distributed import Client
    except ImportError as exc:
        raise ImportError(
            f"--scheduler needs dask.distributed ({exc}): pip install 'handflow[cluster]' here and on the workers"
        ) from exc
    try:
        return Client(scheduler, timeout=CONNECT_TIMEOUT)
    except OSError as exc:
        raise ValueError(
            f"no dask scheduler answers at {scheduler} ({exc}); start one with 'dask scheduler' and workers with "
            f"'dask worker {scheduler}' (docs/segmentation.md)"
        ) from exc


CONNECT_TIMEOUT = "10s"  # how long --scheduler waits for the scheduler to answer


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
        t0 = time.perf_counter()
        fold = replace(self.run_fold(held), seconds=time.perf_counter() - t0)
        if self.enroll:
            self.progress(f"  {fold_note(fold, self.known)}")
        return fold

    def _run_folds(self) -> list[FoldResult]:
        """Every fold's result in recording order: one after the other, over ``jobs`` local
        processes, or on the dask cluster of ``scheduler`` (joblib either way; module docstring);
        progress per fold."""
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
        if self.scheduler and todo:
            with cluster_client(self.scheduler) as client, parallel_config(backend="dask"):
                jobs = max(1, len(client.scheduler_info()["workers"]))
                self.progress(f"{len(todo)} folds on the dask cluster at {self.scheduler} ({jobs} workers)")
                self._parallel(-1, todo, finished)
        elif jobs > 1:
            with parallel_config(backend="loky", inner_max_num_threads=1):
                self._parallel(jobs, todo, finished)
        else:
            with threadpool_limits(1):  # as in a worker: BLAS sums in the same order whatever ``jobs``
                for k, held in todo:
                    finished(held, self._announced_fold(k, held))
        return [done[h] for h in names]

    def _parallel(self, jobs: int, todo: list[tuple[int, str]], finished: Callable) -> None:
        """The folds ``todo`` over ``jobs`` workers of joblib's current backend, each reported to
        ``finished`` as it ends; a fold that fails stops the others."""
        tasks = Parallel(n_jobs=jobs, return_as="generator_unordered")(
            delayed(_shipped_fold)(self, k, held) for k, held in todo
        )
        for fold in tasks:
            finished(fold.recording, fold)

    def _cached_method_fold(self, held: str, name: str, compute: Callable[[], MethodFold]) -> MethodFold:
        """Batch method ``name``'s part of the fold of ``held``: from ``cache`` when an earlier run
        computed it for the same recordings, settings and code, else ``compute()`` (kept there)."""
        store = self._method_store(name)
        kept = store.load(held) if store else None
        if kept is not None:
            self.progress(f"  {held}: {name} taken from {store.path(held)}")
            return kept
        caught = Counter()
        with counted_warnings(caught):
            part = replace(compute(), warnings=dict(caught))
        if store:
            store.save(part)
        return part

    def _method_store(self, name: str) -> FoldCheckpoints | None:
        """The ``cache`` of batch method ``name``'s parts of folds, keyed by the data, every setting
        that moves its figures (not the other methods: a run that adds one reuses the others'),
        the choices of ``--params`` and the code; None without a cache."""
        if not self.cache:
            return None
        if name not in self._stores:
            settings = {k: v for k, v in self._parameters().items() if k not in ("dataset", "grids", "params_from")}
            settings.update(
                method=name,
                grid=REGISTRY[name].grid(self.quick),
                replays=self._replaying(REGISTRY[name]),
                chosen=self.chosen.by_method[name] if self.chosen else None,
                random_state=self.random_state,
            )
            digest = settings_digest(self.data.recordings, self.data.class_names, settings)
            self._stores[name] = FoldCheckpoints(
                Path(self.cache) / UNSAFE.sub("_", name), digest, MethodFold, self.progress
            )
        return self._stores[name]

    def _checkpoints(self) -> FoldCheckpoints | None:
        """The store of finished folds (``checkpoints``), keyed by the data and every setting that
        moves a figure; None without one."""
        if not self.checkpoints:
            return None
        settings = {k: v for k, v in self._parameters().items() if k != "dataset"}
        settings.update(methods=list(self.methods), random_state=self.random_state)
        digest = settings_digest(self.data.recordings, self.data.class_names, settings)
        return FoldCheckpoints(self.checkpoints, digest, FoldResult, self.progress)
