"""Online / incremental UKR/CLM segmentation (docs/segmentation.md §C).

:class:`OnlineCLMSegmenter` keeps a sliding window of the last ``window`` observations.  Each new
observation is projected onto the candidates once; only the compatibilities that involve it (one
new band row per layer) are computed, the others shift with the window.  The CLM is then re-run
**warm**: kept neurons start from their previous activities (biased towards their previous
winner) plus small random values on every layer (so the start is not unique), the new column
starts small and random, and the temperature starts at ``warm_temperature · λ_max`` instead of
``λ_max``.  When later evidence changes the label of an earlier observation in the window, a
revision is reported — only once it is *confirmed* (documented choice, see
:meth:`OnlineCLMSegmenter._revisions`): the changed label must have held for ``confirm``
consecutive updates, and observations within ``edge`` of the window's oldest end (they are about
to leave and have lost their older neighbours) are never revised.  A confirmed revision moves the
published segment boundaries (:class:`SegmentTracker`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .candidates import CandidateSet
from .clm_segmenter import REJECTED, CLMSegmenter
from .compatibility import background_band, candidate_band, order_rating, pair_error


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
    """Result of one :meth:`OnlineCLMSegmenter.update`."""

    index: int
    label: int
    scores: np.ndarray
    sweeps: int
    converged: bool
    events: list[SegmentChange] = field(default_factory=list)


class OnlineCLMSegmenter(CLMSegmenter):
    """Sliding-window warm-started CLM segmentation of a stream.

    Takes the parameters of :class:`CLMSegmenter` (with ``spectral="gershgorin"`` and
    ``max_sweeps=150`` by default) plus the ones below.  Documented choice: ``max_sweeps`` is a
    per-update budget — an online update is anytime: an unconverged solution still gives labels
    (the strongest layer per observation) and the next update continues warm from it, which bounds
    the per-sample latency (a cold check or an unlucky warm run could otherwise take 1000 sweeps).

    window : number of most recent observations the CLM sees (thesis-free choice; 200 = 2 s at 100 Hz).
    warm_start : re-use the previous solution (False = every update solves cold, for comparison).
    warm_temperature : start temperature of a warm run as a fraction of λ_max.
    warm_bias : strength of the bias towards the previous winner (times the mean winning activity).
    fresh : the most recent observations that start unbiased; ``None`` = 2H.
    cold_every : every this many warm updates also solve cold and keep the solution of lower
        energy (the warm dynamics can stay in the local minimum of a running segment that
        swallows the next motion; ``None`` = never).
    confirm : a changed label of an already published observation is reported as a revision only
        after it held for this many consecutive updates (1 = report every change at once).
    edge : observations this close to the window's oldest end are not revised; ``None`` = H.
    """

    def __init__(
        self,
        candidates: CandidateSet,
        window: int = 200,
        warm_start: bool = True,
        warm_temperature: float = 0.05,
        warm_bias: float = 1.0,
        fresh: int | None = None,
        cold_every: int | None = 10,
        confirm: int = 5,
        edge: int | None = None,
        **clm_params,
    ) -> None:
        clm_params.setdefault("spectral", "gershgorin")
        clm_params.setdefault("max_sweeps", 150)
        super().__init__(candidates, **clm_params)
        if window < 2:
            raise ValueError(f"window must hold at least 2 observations, got {window}")
        self.window = window
        self.warm_start = warm_start
        self.warm_temperature = warm_temperature
        self.warm_bias = warm_bias
        self.fresh = 2 * self.history if fresh is None else int(fresh)
        self.cold_every = cold_every
        if confirm < 1:
            raise ValueError(f"confirm must be >= 1 update, got {confirm}")
        self.confirm = int(confirm)
        self.edge = self.history if edge is None else int(edge)
        self.reset()

    @classmethod
    def _get_param_names(cls) -> list[str]:
        """The window parameters and every :class:`CLMSegmenter` parameter (``**clm_params``)."""
        own = ["window", "warm_start", "warm_temperature", "warm_bias", "fresh", "cold_every", "confirm", "edge"]
        return sorted(set(CLMSegmenter._get_param_names()) | set(own))

    def reset(self) -> None:
        """Forget the stream."""
        m = self._n_layers()
        self._radius, self._span, self._width = self.widths()
        self._rows = self._source_rows(m)  # per-observation source buffers (window, m), slid together
        self._band = np.zeros((m, self.window, self._width))
        self._x: np.ndarray | None = None
        self._labels = np.zeros(0, dtype=int)  # current CLM labels of the window
        self._published = np.zeros(0, dtype=int)  # labels last reported for the window
        self._pending = np.zeros(0, dtype=int)  # consecutive updates a differing label held
        self._pending_label = np.zeros(0, dtype=int)  # the label those updates held
        self.n = 0  # observations in the window
        self.seen = 0  # observations consumed in total
        self.segments = SegmentTracker(memory=self.window)
        self.since_cold = 0

    def _n_layers(self) -> int:
        return len(self.candidates)

    def _source_rows(self, m: int) -> dict[str, np.ndarray]:
        """Buffers of what the source gives per observation: latent times and errors per candidate."""
        return {"latent": np.zeros((self.window, m)), "errors": np.zeros((self.window, m))}

    def _recent_band(self, lo: int, j: int) -> np.ndarray:
        """Band (m, j − lo + 1, width) of the observations ``lo…j`` of the window."""
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
        """Labels as reported so far (on arrival, then by confirmed revisions), oldest first."""
        return self._published.copy()

    def update(self, y: np.ndarray) -> OnlineUpdate:
        """Consume one observation (d,) and re-segment the window."""
        proj = self.candidates.project(np.asarray(y, dtype=float).reshape(1, -1))
        return self.update_projected(proj.latent_time[0], proj.errors[0])

    def _append(self, **rows: np.ndarray) -> None:
        """Add one observation's source rows (:meth:`_source_rows`) and its new band entries."""
        if self.n == self.window:  # slide: drop the oldest observation everywhere
            for buf in self._rows.values():
                buf[:-1] = buf[1:]
            self._band[:, :-1] = self._band[:, 1:]
            self._band[:, -1] = 0.0
            if self._x is not None:
                self._x = self._x[:, 1:]
            self._labels = self._labels[1:]
            self._published = self._published[1:]
            self._pending = self._pending[1:]
            self._pending_label = self._pending_label[1:]
        else:
            self.n += 1
        j = self.n - 1
        for name, row in rows.items():
            self._rows[name][j] = row
        lo = max(0, j - self._width)
        recent = self._recent_band(lo, j)
        for k in range(1, j - lo + 1):  # pair (j − k, j) sits in row j − k, column k − 1
            self._band[:, j - k, k - 1] = recent[:, j - k - lo, k - 1] if k <= self._span else 0.0
        self.seen += 1

    def layers(self) -> tuple[np.ndarray, np.ndarray]:
        """Bands and diagonals of all layers over the current window (background last)."""
        n = self.n
        bg, bg_diag = background_band(
            n,
            self._width,
            self.background_strength(n),
            self._radius,
        )
        band = np.concatenate([self._band[:, :n], bg[None]], axis=0)
        return band, np.r_[np.zeros(self._n_layers()), bg_diag]

    def update_projected(self, latent_time: np.ndarray, errors: np.ndarray) -> OnlineUpdate:
        """:meth:`update` for an observation already projected onto all candidates."""
        self._append(
            latent=np.asarray(latent_time, dtype=float), errors=np.asarray(errors, dtype=float) * self.error_scale
        )
        return self._segment()

    def _segment(self) -> OnlineUpdate:
        """Re-run the CLM over the window (warm when possible) and publish the newest label."""
        band, diag = self.layers()
        solver = self._solver()
        lam = solver.spectral_scale(band, diag)
        warm = self.warm_start and self._x is not None
        result = None
        if warm:
            x0 = solver.initial_activities((band.shape[0], self.n))
            x0[:, :-1] += self.warm_bias * self._warm_template()
            result = solver.solve(band, diag, x0=x0, temperature=self.warm_temperature * max(lam, 0.0), lambda_max=lam)
            self.since_cold += 1
        if not warm or (self.cold_every and self.since_cold >= self.cold_every):
            cold = solver.solve(band, diag, lambda_max=lam)
            self.since_cold = 0
            if result is None or cold.energy < result.energy:
                result = cold
        self._store(result)
        self._x = result.activities
        self._labels = self.labels_.copy()
        newest = int(self._labels[-1])
        events = self._revisions()
        self._published = np.r_[self._published, newest]
        self._pending = np.r_[self._pending, 0]
        self._pending_label = np.r_[self._pending_label, newest]
        events += self.segments.update(self.seen - 1, newest)
        return OnlineUpdate(
            index=self.seen - 1,
            label=newest,
            scores=result.activities[:-1, -1].copy(),
            sweeps=result.sweeps,
            converged=result.converged,
            events=events,
        )

    def replay(self, Y: np.ndarray) -> np.ndarray:
        """Feed a whole (N, d) stream through :meth:`update` (the node's code path) from a fresh
        state; returns each observation's *final* published label (on arrival, then changed only
        by confirmed revisions) — what a subscriber to the node's labels and events ends up with."""
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        self.reset()
        labels = np.empty(len(Y), dtype=int)
        for up in self._updates(Y):
            labels[up.index] = up.label
            for ev in up.events:
                if ev.kind == "revision":
                    labels[ev.start : ev.end + 1] = ev.label
        return labels

    def _updates(self, Y: np.ndarray):
        """Updates of a whole stream, the source evaluated once for all of it."""
        proj = self.candidates.project(Y)
        for t in range(len(Y)):
            yield self.update_projected(proj.latent_time[t], proj.errors[t])

    def _warm_template(self) -> np.ndarray:
        """Bias towards each kept observation's previous winner, scaled by the mean winning activity.

        Documented choices: only observations previously assigned to a *candidate* layer are
        biased — rejected (background) ones restart like new neurons, so a new motion first
        rejected for lack of support can still form its group later; and the ``fresh`` most recent
        observations are never biased, so a running segment cannot simply swallow the start of the
        next motion.
        """
        prev = self._x
        cols = np.arange(prev.shape[1])
        winners = prev.argmax(axis=0)
        top = prev[winners, cols]
        scale = float(top[top > 0].mean()) if (top > 0).any() else 0.0
        out = np.zeros_like(prev)
        keep = (top > 0) & (winners < prev.shape[0] - 1) & (cols < prev.shape[1] - self.fresh)
        out[winners[keep], cols[keep]] = scale
        return out

    def _revisions(self) -> list[SegmentChange]:
        """Confirmed revisions of published labels, one event per (old → new) run, each followed by
        the segment boundaries it moved.

        Documented choice: observation ``i`` is revised when its current label differs from the
        published one and has differed (with the same new label) for ``confirm`` consecutive
        updates, and ``i`` is not among the ``edge`` oldest observations of a full window (it has
        lost its older neighbours).  Waiting for a minimum age instead was tried and rejected: it
        revises the same observations but releases them one per update, as many single-point events.
        """
        new, old = self._labels[:-1], self._published
        differs = new != old
        held = differs & (self._pending_label == new)
        self._pending = np.where(differs, np.where(held, self._pending + 1, 1), 0)
        self._pending_label = new.copy()
        ready = self._pending >= self.confirm
        if self.n == self.window:
            ready[: self.edge] = False
        events: list[SegmentChange] = []
        base = self.window_start
        for i in np.flatnonzero(ready).tolist():
            last = events[-1] if events else None
            if last is not None and last.end == base + i - 1 and last.label == new[i] and last.previous == old[i]:
                last.end = base + i
            else:
                events.append(SegmentChange("revision", int(new[i]), base + i, base + i, int(old[i])))
        self._published[ready] = new[ready]
        self._pending[ready] = 0
        return [out for ev in events for out in [ev, *self.segments.revise(ev.start, ev.end, ev.label)]]


__all__ = ["OnlineCLMSegmenter", "OnlineUpdate", "SegmentChange", "SegmentTracker", "REJECTED"]
