"""The preview protocol on continuous recordings (docs/segmentation.md, "Which protocol when"):
cross-validated grid search for exploring, in minutes instead of the nested protocol's hours.

Every candidate of a method (view × grid point) is calibrated once on the *outer* folds
themselves — each recording held out in turn, the others training — by the nested protocol's own
objective and calibration rule (:mod:`._calibration`: the mean of the known accuracy and the
rejection of pseudo-unknowns, the rejection value included, and the fallback rule), with the
nested protocol's successive halving over the candidates (:mod:`._selection`: screened with cheap
models, the best third refined at full fidelity).  Each method gets one choice for all folds, the
candidate with the best pooled objective, and the reported labels of every held-out recording are
that candidate's, at that rejection value: there is no final refit, the refined fits are the
reported fits.  Labels of classes outside ``known`` never count in a choice: their frames are
neither known nor pseudo-unknown (:meth:`._calibration.InnerFoldCalibration.validation`).

The figure is the best pooled objective's candidate scored on the recordings that chose it, as
scikit-learn's ``best_score_``: optimistic by the luck of that choice (:mod:`._protocols`).  The
methods run in groups of shared fits (``fit_key``: ``ukr_clm`` with ``ukr_only``, ``minirocket``
with ``clm_minirocket``), the groups over ``jobs`` processes, the manifold methods' group first.
"""

from __future__ import annotations

import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext

from joblib import Parallel, delayed, parallel_config
from threadpoolctl import threadpool_limits

from ._fidelity import Fidelity
from ._fold_result import FoldResult, MethodFold
from ._methods import REGISTRY
from ._report import choice_summary
from ._third_party import counted_warnings


def _in_worker(evaluator, task: str, name: str, *args):
    """``evaluator.<task>(REGISTRY[name], *args)`` in a worker process (one BLAS thread): a split's
    models (:meth:`._calibration.InnerFoldCalibration.split_models`) or a held-out recording's
    online replays (:meth:`._recordings.RecordingsEvaluator._replayed`)."""
    with threadpool_limits(1):
        return getattr(evaluator, task)(REGISTRY[name], *args)


class PreviewRunner:
    """The preview part of :class:`._recordings.RecordingsEvaluator`."""

    def _preview_groups(self) -> list[list[str]]:
        """The batch methods by the fits they share (``fit_key``), the groups that fit class
        manifolds first (they take longest, so the other workers take the rest meanwhile)."""
        groups: dict[str, list[str]] = {}
        for name in self.methods:
            if REGISTRY[name].batch is None:
                groups.setdefault(REGISTRY[name].fit_key, []).append(name)
        return sorted(groups.values(), key=lambda g: not any(REGISTRY[m].manifolds for m in g))

    def _warm(self, method, candidates: list[tuple[list, dict]], fidelity: Fidelity) -> None:
        """Before the preview calibrates ``candidates`` (their splits and parameters) at
        ``fidelity``: every split's models (the fits, states and pseudo-unknowns' refits) computed
        over ``jobs`` processes and kept here; the calibration's labels follow in this process.
        Nothing in the nested protocol, whose folds are the parallel unit."""
        if not self.preview or self.jobs < 2:
            return
        todo = {}
        for splits, params in candidates:
            present = self.present(splits)
            for v, rest in splits:
                key = self._split_key(method, v, rest, params, fidelity, present)
                if key not in self._cache:
                    todo[key] = (v, rest, params, fidelity, present)
        if not todo:
            return
        done = self._over_workers("split_models", method, list(todo.values()))
        self._cache.update(zip(todo, done))

    def _over_workers(self, task: str, method, calls: list[tuple]) -> list:
        """``self.<task>(method, *call)`` of every call over ``jobs`` processes (:func:`_in_worker`)."""
        with parallel_config(backend="loky", inner_max_num_threads=1):
            return Parallel(n_jobs=min(self.jobs, len(calls)))(
                delayed(_in_worker)(self, task, method.name, *call) for call in calls
            )

    def _preview_folds(self) -> tuple[list[FoldResult], dict]:
        """Every fold's result (recording order) and the timing of the preview."""
        groups, t0 = self._preview_groups(), time.perf_counter()
        self.progress(
            f"preview: every candidate scored on the {len(self.data.recordings)} leave-one-recording-out folds, "
            f"the fits over {self.jobs} process(es)"
        )
        # as in a worker: BLAS sums in the same order whatever ``jobs``; a calibration labels its
        # folds over ``jobs`` threads (:meth:`._calibration.InnerFoldCalibration._each_split`)
        with threadpool_limits(1), ThreadPoolExecutor(self.jobs) if self.jobs > 1 else nullcontext() as threads:
            self._threads = threads
            try:
                done = [self._preview_group(g) for g in groups]
            finally:
                self._threads = None
        parts = {name: folds for found, _ in done for name, folds in found.items()}
        names = self.data.names()
        folds = [
            self._fold_result(
                held,
                self.data.recordings[k].y,
                [parts[name][k] for name in parts],
                self._untrained(self.data.without(held)),
            )
            for k, held in enumerate(names)
        ]
        seconds = {m: phases for _, timing in done for m, phases in timing.items()}
        timing = {
            "methods": {m: {p: round(v, 2) for p, v in phases.items()} for m, phases in seconds.items()},
            "wall_s": round(time.perf_counter() - t0, 2),
        }
        return folds, timing

    def _preview_group(self, group: list[str]) -> tuple[dict[str, list[MethodFold]], dict]:
        """The methods of ``group`` (sharing fits): each one's choice on the outer folds and its
        parts of every fold; the seconds per method and phase."""
        self._cache, self._fold_choices, self._timing = {}, {}, {}
        names = self.data.names()
        views = {held: self.views(held) for held in names}
        splits = {key: [(views[h][key][1], views[h][key][0]) for h in names] for key in views[names[0]]}
        out = {}
        for name in group:
            caught = Counter()
            with counted_warnings(caught):
                out[name] = self._preview_method(name, splits)
            for part in out[name]:
                part.warnings = dict(caught) if part is out[name][0] else {}
        return out, self._timing

    def _preview_method(self, name: str, splits: dict) -> list[MethodFold]:
        """Method ``name``'s one choice for all folds (:meth:`_select` on the outer folds) and,
        per fold, the refined fits' labels of the held-out recording at it and over the sweep."""
        method, t0 = REGISTRY[name], time.perf_counter()
        with self._timed(name, "selection"):
            choice = self._select(name, splits)
        selected = choice.selected()
        self.progress(
            f"preview: {name} {choice_summary(selected)} for all folds (pooled objective {choice.objective:.3f}) "
            f"in {time.perf_counter() - t0:.1f} s"
        )
        with self._timed(name, "labelling"):
            fits = self._refined(method, choice.params, splits)
            grid = method.reject_grid(fits[0][0], [state for _, state, _ in fits])
            strict = self._refined(method, choice.strict.params, splits) if choice.fallback else None
        replays = self._replays(method, fits, choice.reject)
        parts = []
        for k, (fitted, state, test) in enumerate(fits):
            with self._timed(name, "labelling"):
                labels = {name: method.labels(fitted, state, choice.reject)}
                sweeps = [self._labels(method, fitted, state, test, r) for r in grid]
                held_strict = None
                if strict is not None:
                    s_fit, s_state, s_test = strict[k]
                    held_strict = self._labels(method, s_fit, s_state, s_test, choice.strict.reject)
            labels.update(replays[k])
            parts.append(
                MethodFold(test.name, name, labels, dict.fromkeys(labels, selected), sweeps, held_strict, {}, {})
            )
        return parts

    def _replays(self, method, fits: list[tuple], reject: float) -> list[dict]:
        """Per fold: the online methods' replays of the refined ``fits`` at ``reject``, the folds
        over ``jobs`` processes."""
        online = self._replaying(method)
        if self.jobs < 2 or not online:
            return [self._replayed(method, fitted, reject, test) for fitted, _, test in fits]
        with self._timed(" + ".join(online), "labelling"):
            return self._over_workers("_replayed", method, [(fitted, reject, test) for fitted, _, test in fits])

    def _refined(self, method, params: dict, splits: dict) -> list[tuple]:
        """Per fold: ``method`` with ``params`` fitted at the refinement's fidelity on the fold's
        training recordings and its state on the held-out recording — the calibration's own
        models, from the cache — and that recording."""
        folds = splits[params["normalise"], params["derived"]]
        present = self.present(folds)
        refine = self.halving.refine
        return [(*self.split_models(method, v, rest, params, refine, present)[:2], v) for v, rest in folds]
