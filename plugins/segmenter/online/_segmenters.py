"""Online / incremental UKR/CLM segmentation (docs/segmentation.md §C).

:class:`OnlineCLMSegmenter` keeps a sliding window of the last ``window`` observations.  Each new
observation is projected onto the candidates once; only the compatibilities that involve it (one
new band row per layer) are computed, the others shift with the window.  Two CLM runs share the
batch solver (:class:`~handflow.plugins.segmenter.clm.CompetitiveLayerModel`):

* the **fast** run gives each observation its label on arrival: the previous activities are kept,
  the new column starts small and random at the batch start temperature, and every column is
  annealed from its own arrival (one temperature per column, ``T ← η T`` per sweep) by
  ``update_sweeps`` sweeps per update — a streaming version of the batch annealing whose cost does
  not grow with the number of sweeps a cold solve needs;
* the **block** run makes the *final* labels: every ``block`` observations a cold, annealed solve of
  the whole window starts — the batch solve, with the batch's parameters — and is advanced
  ``block_sweeps`` sweeps per update; when it ends, the observations in the middle ``block`` of its
  window (the first ones too, at the start of the stream) take its labels for good.  They have
  ``(window − block)/2`` observations of context on either side, where the whole-stream batch
  solution is, in practice, already fixed (docs/benchmarks.md); :meth:`OnlineCLMSegmenter.finish`
  solves what is left at the end of a stream.

A changed label of an already published observation is reported as a revision: from a block run at
once, from the fast run once *confirmed* (documented choice, see :meth:`OnlineCLMSegmenter._revisions`).
A revision moves the published segment boundaries (:class:`SegmentTracker`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..base import REJECTED
from ..clm import CLMRun, CLMSegmenter, default_solver
from ..compatibility import SPIKE_LENGTH, candidate_band, evidence_band, order_rating, pair_error
from ..models import CandidateSet


@dataclass
class SegmentChange:
    """A segment ``start``/``end`` or a label ``revision`` over global indices ``start…end``."""

    kind: str
    label: int
    start: int
    end: int
    previous: int | None = None


class SegmentTracker:
    """Segments as runs of *published* labels: start/end events, moved by confirmed revisions.

    :meth:`update` publishes the newest observation's label (a ``start`` event, and the ``end`` of
    the running segment, when it differs).  :meth:`revise` changes already published labels; the
    boundaries of the affected segments are then re-announced: ``end`` of the segment before the
    revised run (with its new end), ``start`` of the revised run and, if it is closed, its ``end``
    and the ``start`` of the segment after it.  A re-announced boundary supersedes any earlier event
    for the same segment (same label, overlapping indices).  ``memory`` published labels are kept.
    """

    def __init__(self, memory: int = 1000) -> None:
        self.memory = int(memory)
        self.first = 0  # global index of labels[0]
        self.labels: list[int] = []
        self.current: tuple[int, int] | None = None  # (label, start index) of the running segment

    def update(self, index: int, label: int) -> list[SegmentChange]:
        if not self.labels:
            self.first = index
        self.labels.append(int(label))
        if len(self.labels) > self.memory:
            del self.labels[0]
            self.first += 1
        if self.current is not None and self.current[0] == label:
            return []
        events = []
        if self.current is not None:
            events.append(SegmentChange("end", self.current[0], self.current[1], index - 1))
        self.current = (label, index)
        events.append(SegmentChange("start", label, index, index))
        return events

    def _run(self, pos: int) -> tuple[int, int]:
        """First and last list position of the run of equal labels around ``pos``."""
        lo, hi, lab = pos, pos, self.labels[pos]
        while lo > 0 and self.labels[lo - 1] == lab:
            lo -= 1
        while hi + 1 < len(self.labels) and self.labels[hi + 1] == lab:
            hi += 1
        return lo, hi

    def revise(self, start: int, end: int, label: int) -> list[SegmentChange]:
        """Published labels ``start…end`` (global) become ``label``; returns the moved boundaries."""
        a, b = max(start - self.first, 0), min(end - self.first, len(self.labels) - 1)
        if a > b:
            return []
        self.labels[a : b + 1] = [int(label)] * (b - a + 1)
        lo, hi = self._run(a)
        g = self.first
        events = []
        if lo > 0:
            plo, _ = self._run(lo - 1)
            events.append(SegmentChange("end", self.labels[lo - 1], g + plo, g + lo - 1))
        events.append(SegmentChange("start", label, g + lo, g + lo))
        if hi + 1 < len(self.labels):
            events.append(SegmentChange("end", label, g + lo, g + hi))
            nlo, _ = self._run(hi + 1)  # == hi + 1
            events.append(SegmentChange("start", self.labels[hi + 1], g + nlo, g + nlo))
            if self.current is not None and self.current[1] <= g + hi:
                self.current = (self.labels[-1], g + self._run(len(self.labels) - 1)[0])
        else:
            self.current = (label, g + lo)
        return events


@dataclass
class OnlineUpdate:
    """Result of one :meth:`OnlineCLMSegmenter.push`."""

    index: int
    label: int
    scores: np.ndarray
    sweeps: int
    converged: bool
    events: list[SegmentChange] = field(default_factory=list)


class OnlineCLMSegmenter(CLMSegmenter):
    """Sliding-window CLM segmentation of a stream: fast labels on arrival, batch-equal final labels.

    Takes the parameters of :class:`CLMSegmenter` (its default solver with ``spectral="gershgorin"``:
    the exact λ_max costs more than the sweeps here) plus the ones below.

    window : number of most recent observations the CLM sees (200 = 2 s at 100 Hz).
    tail : observations the fast run solves (the newest ones; the older ones' activities are a
        fixed context); ``None`` = the whole window (every update solves the window cold: the
        baseline of docs/benchmarks.md).
    update_eta : annealing factor per sweep of the fast run (the batch's η = 0.98 needs ~300
        sweeps, its 0.998 for headed candidates the 1000-sweep cap; the fast run is a quick look
        at the newest observations).
    update_sweeps : sweep budget of the fast run per update (anytime: an unconverged run still
        gives labels).
    block : stride of the block runs (observations finalised per block run); ``None`` = half the
        window; 0 = no block runs (the fast run's labels, with confirmed revisions, are final).
        A block run is one run of the batch solver (the batch default ``restarts=1``).
    block_sweeps : sweeps of the running block run per update; ``None`` = the solver's
        ``max_sweeps`` spread over the ``block`` updates until the next run is due, so a run that
        uses its whole budget ends on time; a run still going when its first unfinalised
        observation is about to leave the window (or the next run is due) is finished at once.
    confirm : a changed label from the fast run is reported as a revision only after it held for
        this many consecutive updates (1 = report every change at once).
    edge : observations this close to the window's oldest end are not revised by the fast run;
        ``None`` = H.

    The segment rules ``min_progress`` and ``max_fit_ratio`` (:class:`CLMSegmenter`) apply to the
    *final* labels: each block run's labels are filtered over its window
    (:func:`..compatibility.reject_segments`) before the middle block takes them; a segment cut by
    the window's edge (the stream goes on beyond it) is not judged, as only part of it is in view;
    the labels on arrival are not filtered (documented choice, docs/segmentation.md).
    """

    SPECTRAL = "gershgorin"  # the exact λ_max costs more than the sweeps of a window

    def __init__(
        self,
        candidates: CandidateSet,
        window: int = 200,
        tail: int | None = 30,
        update_eta: float = 0.9,
        update_sweeps: int = 60,
        block: int | None = None,
        block_sweeps: int | None = None,
        confirm: int = 5,
        edge: int | None = None,
        **clm_params,
    ) -> None:
        if clm_params.get("solver") is None:
            clm_params["solver"] = default_solver(candidates, spectral=self.SPECTRAL)
        super().__init__(candidates, **clm_params)
        if window < 2:
            raise ValueError(f"window must hold at least 2 observations, got {window}")
        block = window // 2 if block is None else int(block)
        if not 0 <= block <= window:
            raise ValueError(f"block must lie in 0…window ({window}), got {block}")
        if block_sweeps is None:
            block_sweeps = -(-int(self.solver.max_sweeps) // max(block, 1))  # ceil: the cap within one block
        if update_sweeps < 1 or block_sweeps < 1:
            raise ValueError(f"update_sweeps and block_sweeps must be >= 1, got {update_sweeps}, {block_sweeps}")
        if confirm < 1:
            raise ValueError(f"confirm must be >= 1 update, got {confirm}")
        self.window = window
        self.tail = window if tail is None else min(int(tail), window)
        if self.tail < 1:
            raise ValueError(f"tail must be >= 1 observation, got {tail}")
        self.update_eta = update_eta
        self.update_sweeps = int(update_sweeps)
        self.block = int(block)
        self.block_sweeps = int(block_sweeps)
        self.confirm = int(confirm)
        self.edge = self.history if edge is None else int(edge)
        self.reset()

    @classmethod
    def _get_param_names(cls) -> list[str]:
        """The window parameters and every :class:`CLMSegmenter` parameter (``**clm_params``)."""
        own = ["window", "tail", "update_eta", "update_sweeps", "block", "block_sweeps", "confirm", "edge"]
        return sorted(set(CLMSegmenter._get_param_names()) | set(own))

    def reset(self) -> None:
        """Forget the stream."""
        m = self._n_layers()
        self._radius, self._span, self._width = self.widths()
        self._rows = self._source_rows(m)  # per-observation source buffers (window, m), slid together
        self._band = np.zeros((m + (self.reconstruction == "relative"), self.window, self._width))  # + background
        self._labels = np.zeros(0, dtype=int)  # current labels of the window (fast run, then final)
        self._published = np.zeros(0, dtype=int)  # labels last reported for the window
        self._final = np.zeros(0, dtype=bool)  # labels fixed by a block run
        self._x = np.zeros((m + 1, 0))  # activities: fast run's, block run's when final
        self._pending = np.zeros(0, dtype=int)  # consecutive updates a differing label held
        self._pending_label = np.zeros(0, dtype=int)  # the label those updates held
        self._run: tuple | None = None  # block run: its first column, end of its finalised part, run, projection
        self._finalised = 0  # global index of the first observation without a final label
        self.n = 0  # observations in the window
        self.seen = 0  # observations consumed in total
        self.segments = SegmentTracker(memory=self.window)
        self._stream = self.candidates.stream() if self.candidates is not None else None

    def _n_layers(self) -> int:
        return len(self.candidates)

    def _source_rows(self, m: int) -> dict[str, np.ndarray]:
        """Buffers of what the source gives per observation: latent times and errors per candidate,
        and (``reconstruction="relative"``) the evidence per candidate and the null model."""
        rows = {"latent": np.zeros((self.window, m)), "errors": np.zeros((self.window, m))}
        if self.candidates is not None and self.candidates.headings.active:  # for the fit rule
            rows["reversed_errors"] = np.zeros((self.window, m))
        if self.reconstruction == "relative":  # latent times and errors for the segment rules only
            rows["evidence"] = np.zeros((self.window, m + 1))
        return rows

    def _recent_band(self, lo: int, j: int) -> np.ndarray:
        """Band (m, j − lo + 1, width) of the observations ``lo…j`` of the window."""
        if "evidence" in self._rows:  # per-observation evidence (relative errors, or a scorer's)
            return evidence_band(self._rows["evidence"][lo : j + 1], self._width, self._span)
        return candidate_band(
            self._rows["latent"][lo : j + 1],
            self._rows["errors"][lo : j + 1],
            self._width,
            order_rating(self.order_rating),
            pair_error(self.pair_error),
            self.order_path,
            self.candidates.seams(),
        )

    @property
    def window_start(self) -> int:
        """Global index of the oldest observation in the window."""
        return self.seen - self.n

    @property
    def window_labels(self) -> np.ndarray:
        """Current labels of the observations in the window (oldest first)."""
        return self._labels.copy()

    @property
    def published_labels(self) -> np.ndarray:
        """Labels as reported so far (on arrival, then by revisions), oldest first."""
        return self._published.copy()

    def push(self, y: np.ndarray) -> OnlineUpdate:
        """Consume one observation (d,) and re-segment the window."""
        y = np.asarray(y, dtype=float).reshape(1, -1)
        if not np.isfinite(y).all():  # checked before it enters the delay buffer
            raise ValueError("observations hold NaN/inf; drop or repair those rows before recognition")
        proj = self._stream.project(y)
        return self.update_projected(*proj.row())

    def update(self, y: np.ndarray) -> OnlineUpdate:
        """:meth:`push` (its name before the streaming contract, docs/segmentation.md)."""
        return self.push(y)

    def _append(self, **rows: np.ndarray) -> None:
        """Add one observation's source rows (:meth:`_source_rows`) and its new band entries."""
        if self.n == self.window:  # slide: drop the oldest observation everywhere
            for buf in self._rows.values():
                buf[:-1] = buf[1:]
            self._band[:, :-1] = self._band[:, 1:]
            self._band[:, -1] = 0.0
            for name in ("_labels", "_published", "_final", "_pending", "_pending_label"):
                setattr(self, name, getattr(self, name)[1:])
            self._x = self._x[:, 1:]
        else:
            self.n += 1
        j = self.n - 1
        for name, row in rows.items():
            self._rows[name][j] = row
        # the latent path bridges a spike (compatibility.bridged_latent) only once the observation
        # after it is known: the pairs ending at the SPIKE_LENGTH observations before j are made again
        reach = 0 if "evidence" in self._rows else SPIKE_LENGTH
        lo = max(0, j - self._width - 2 * reach)
        recent = self._recent_band(lo, j)
        for end in range(max(j - reach, 0), j + 1):
            k = np.arange(1, min(end - lo, self._span) + 1)  # pair (end − k, end): row end − k, column k − 1
            self._band[:, end - k, k - 1] = recent[:, end - k - lo, k - 1]
        self.seen += 1

    def layers(self) -> tuple[np.ndarray, np.ndarray]:
        """Bands and diagonals of all layers over the current window (background last).

        Documented choice: λ_bg is that of the stream so far (``seen`` observations), not of the
        window — the thesis rule ``1 − 10/N`` takes N = the length of the segmented sequence, and the
        whole-stream batch uses the stream's length.
        """
        return self.with_background(self._band[:, : self.n], length=self.seen)

    def update_projected(
        self, latent_time: np.ndarray, errors: np.ndarray, reversed_errors: np.ndarray | None = None
    ) -> OnlineUpdate:
        """:meth:`push` for an observation already projected onto all candidates
        (``reversed_errors``: with its headings turned round, :mod:`..features`)."""
        errors = np.asarray(errors, dtype=float) * self.error_scale
        rows = {"latent": np.asarray(latent_time, dtype=float), "errors": errors}
        if "reversed_errors" in self._rows:
            if reversed_errors is None:
                raise ValueError("candidates with heading channels need each observation's reversed_errors")
            rows["reversed_errors"] = np.asarray(reversed_errors, dtype=float) * self.error_scale
        if self.reconstruction == "relative":
            rows["evidence"] = self.relative_evidence(errors[None])[0]
        self._append(**rows)
        return self._segment()

    def _segment(self) -> OnlineUpdate:
        """Re-run the CLM over the window (fast run, block runs) and publish the newest label."""
        band, diag = self.layers()
        solver = self._solver()
        lam = solver.spectral_scale(band, diag)
        tail = min(self.n, self.tail)
        x0 = np.concatenate([self._x, solver.initial_activities((band.shape[0], 1))], axis=1)
        x0[:, -tail:] = solver.initial_activities((band.shape[0], tail))
        run = solver.start(band, diag, x0=x0, lambda_max=lam, eta=self.update_eta, first=self.n - tail)
        run.advance(self.update_sweeps)
        result = run.result(energy=False)
        self._store(result)
        self._x = result.activities
        labels = np.r_[self._labels, REJECTED]
        labels[-tail:] = np.where(np.r_[self._final, False][-tail:], labels[-tail:], self.labels_[-tail:])
        self._labels = labels
        newest = int(labels[-1])
        events = self._revisions()
        self._published = np.r_[self._published, newest]
        self._final = np.r_[self._final, False]
        self._pending = np.r_[self._pending, 0]
        self._pending_label = np.r_[self._pending_label, newest]
        events += self.segments.update(self.seen - 1, newest)
        events += self._blocks(band, diag, lam)
        return OnlineUpdate(
            index=self.seen - 1,
            label=newest,
            scores=result.activities[:-1, -1].copy(),
            sweeps=run.sweeps,
            converged=run.converged,
            events=events,
        )

    def _blocks(self, band: np.ndarray, diag: np.ndarray, lam: float) -> list[SegmentChange]:
        """Advance the running block run, finalise its labels when it ends, start the next one."""
        if not self.block:
            return []
        events = []
        due = self.seen % self.block == 0
        # the run must end before its first unfinalised observation leaves the window (a full
        # window drops its oldest observation at the next update)
        last_chance = due or (self.n == self.window and self._finalised <= self.window_start)
        if self._run is not None and self._run[2].advance(
            self._solver().max_sweeps if last_chance else self.block_sweeps
        ):
            events = self._finalise(*self._run)
            self._run = None
        stop = self.seen - (self.window - self.block) // 2  # observations with that much context after them
        if due and stop > self._finalised:
            run = self._solver().start(band, diag, lambda_max=lam)
            self._run = (self.window_start, stop, run, self._window_projection())
        return events

    def _window_projection(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | None:
        """The window's latent times, errors and reversed errors (N, M) each (None without heading
        channels), kept for the segment rules (None without them)."""
        if not self.segment_rules:
            return None
        reversed_errors = self._rows.get("reversed_errors")
        return (
            self._rows["latent"][: self.n].copy(),
            self._rows["errors"][: self.n].copy(),
            None if reversed_errors is None else reversed_errors[: self.n].copy(),
        )

    def _finalise(
        self,
        first: int,
        stop: int,
        run: CLMRun | np.ndarray,
        projection: tuple[np.ndarray, np.ndarray, np.ndarray | None] | None = None,
    ) -> list[SegmentChange]:
        """Fix the labels of observations ``self._finalised … stop − 1`` (global) to those of a
        block run (or given labels) over the observations from ``first`` on, whose latent times and
        errors are ``projection`` (for the segment rules)."""
        labels = self.labels_from(run.result()) if isinstance(run, CLMRun) else run
        if projection is not None:  # a segment cut by the window's edge is not judged: the batch sees it whole
            latent, errors, reversed_errors = projection
            labels = self.reject_segments(
                labels, latent, errors, (first > 0, first + len(labels) < self.seen), reversed_errors
            )
        a, b = self._finalised - self.window_start, min(stop, self.seen) - self.window_start
        if b <= a:
            return []
        self._labels[a:b] = labels[self._finalised - first : stop - first]
        if isinstance(run, CLMRun):  # the fast run's fixed context continues from the final solution
            self._x[:, a:b] = run.x[:, self._finalised - first : stop - first]
        self._final[a:b] = True
        self._finalised = stop
        ready = np.zeros(self.n, dtype=bool)
        ready[a:b] = True
        return self._publish(ready)

    def finish(self) -> list[SegmentChange]:
        """End of stream: complete the running block run, solve the window cold as the batch does
        and fix every label not yet final; returns the revisions (the stream may go on after it)."""
        events = []
        if self._run is not None:
            self._run[2].advance(self._solver().max_sweeps)
            events = self._finalise(*self._run)
            self._run = None
        if self.n:
            labels = self.fit_predict_bands(*self.layers())
            events += self._finalise(self.window_start, self.seen, labels, self._window_projection())
            self._x = self.activities_.copy()
        return events

    def replay(self, Y: np.ndarray) -> np.ndarray:
        """Feed a whole (N, d) stream through :meth:`push` (the node's code path) from a fresh
        state and :meth:`finish` it; returns each observation's *final* published label (on
        arrival, then changed only by revisions) — what a subscriber to the node's labels and
        events ends up with."""
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        self.reset()
        labels = np.empty(len(Y), dtype=int)

        def apply(events):
            for ev in events:
                if ev.kind == "revision":
                    labels[ev.start : ev.end + 1] = ev.label

        for up in self._updates(Y):
            labels[up.index] = up.label
            apply(up.events)
        apply(self.finish())
        return labels

    def _updates(self, Y: np.ndarray):
        """Updates of a whole stream, the source evaluated once for all of it."""
        proj = self.candidates.project(Y)
        for t in range(len(Y)):
            yield self.update_projected(*proj.row(t))

    def _revisions(self) -> list[SegmentChange]:
        """Confirmed revisions by the fast run (labels fixed by a block run excepted).

        Documented choice: observation ``i`` is revised when its current label differs from the
        published one and has differed (with the same new label) for ``confirm`` consecutive
        updates, and ``i`` is not among the ``edge`` oldest observations of a full window (it has
        lost its older neighbours).  Waiting for a minimum age instead was tried and rejected: it
        revises the same observations but releases them one per update, as many single-point events.
        """
        new, old = self._labels[:-1], self._published
        differs = (new != old) & ~self._final
        held = differs & (self._pending_label == new)
        self._pending = np.where(differs, np.where(held, self._pending + 1, 1), 0)
        self._pending_label = new.copy()
        ready = self._pending >= self.confirm
        if self.n == self.window:
            ready[: self.edge] = False
        self._pending[ready] = 0
        return self._publish(np.r_[ready, np.zeros(len(self._labels) - len(ready), dtype=bool)])

    def _publish(self, ready: np.ndarray) -> list[SegmentChange]:
        """Publish the current labels of the ``ready`` window positions that differ from the
        published ones: one revision event per (old → new) run, each followed by the segment
        boundaries it moved."""
        new = self._labels[: len(self._published)]
        old = self._published
        ready = ready[: len(old)] & (new != old)
        events: list[SegmentChange] = []
        base = self.window_start
        for i in np.flatnonzero(ready).tolist():
            last = events[-1] if events else None
            if last is not None and last.end == base + i - 1 and last.label == new[i] and last.previous == old[i]:
                last.end = base + i
            else:
                events.append(SegmentChange("revision", int(new[i]), base + i, base + i, int(old[i])))
        self._published[ready] = new[ready]
        return [out for ev in events for out in [ev, *self.segments.revise(ev.start, ev.end, ev.label)]]


__all__ = ["OnlineCLMSegmenter", "OnlineUpdate", "SegmentChange", "SegmentTracker", "REJECTED"]
