"""The labelled-trajectory protocol's design (docs/segmentation.md §D): its experiments, the
cases built from one split's trajectories, the (N^th, H) pairs of the selection's screen, the
heading-channel candidates and the cross-fitted splits the heading channels are chosen on."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..clm import ETA
from ..datasets import LabelledDataset, Trajectory
from ._methods import TRAJECTORY_METHODS

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
