"""Continuous recordings with one label per frame: loading and training segments (docs/segmentation.md).

Accepted formats (:func:`load_recordings`):

1. **Folder of CSV recordings** — every ``*.csv`` is one recording: a header row, numeric feature
   columns and a last column ``label`` (class name per row; an empty cell = unlabelled).  An
   optional time column (``time``, ``t``, ``timestamp``, ``stamp``) is dropped.
2. **Continuous .npz** — a ``class_names`` array and matching pairs ``X_<name>`` (T, D) and
   ``y_<name>`` (T,) of label indices into ``class_names`` (−1 = unlabelled); an optional
   ``unknown_classes`` array names classes no model is for (``rest`` of ``handflow dataset``): by
   default they are unknown to the evaluation and not trained; other keys (e.g. ``t_<name>``
   timestamps, ``metadata``) are ignored.

:func:`is_continuous` tells these apart from the trajectory formats of :mod:`._trajectories`.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from handflow.framework.files.npz import building, npz_names, read_npz

from ._trajectories import NPZ_HINT, TIME_COLUMNS, DatasetError

UNLABELLED = -1
LABEL_COLUMN = "label"


@dataclass
class Recording:
    """One continuous recording: ``X`` (T, D) features, ``y`` (T,) class indices (−1 = unlabelled)."""

    name: str
    X: np.ndarray
    y: np.ndarray


@dataclass
class RecordingSet:
    """Recordings sharing one feature layout and one list of class names."""

    recordings: list[Recording]
    class_names: list[str]
    columns: list[str]
    source: str = ""
    unknown_classes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        _check(self)

    @property
    def known_classes(self) -> list[str]:
        """The classes modelled by default: all but ``unknown_classes``."""
        return [c for c in self.class_names if c not in self.unknown_classes]

    def names(self) -> list[str]:
        return [r.name for r in self.recordings]

    def without(self, name: str) -> list[Recording]:
        return [r for r in self.recordings if r.name != name]

    def get(self, name: str) -> Recording:
        return next(r for r in self.recordings if r.name == name)


def segments(recordings: list[Recording], classes: list[int]) -> dict[int, list[np.ndarray]]:
    """Maximal runs of one label, per class in ``classes`` (frames of other labels are never used)."""
    out: dict[int, list[np.ndarray]] = {c: [] for c in classes}
    for rec in recordings:
        change = np.flatnonzero(np.diff(rec.y)) + 1
        for lo, hi in zip(np.r_[0, change], np.r_[change, len(rec.y)]):
            c = int(rec.y[lo])
            if c in out and hi - lo >= 2:
                out[c].append(rec.X[lo:hi])
    return out


def is_continuous(path: str | Path) -> bool:
    """True for a continuous .npz (``class_names`` + ``X_``/``y_`` pairs) or a folder of labelled CSVs."""
    p = Path(path).expanduser()
    if p.is_dir():
        files = sorted(p.glob("*.csv"))
        if not files:
            return False
        with files[0].open(newline="") as f:
            header = next(csv.reader(f), [])
        return bool(header) and header[-1].strip().lower() == LABEL_COLUMN
    if p.suffix == ".npz" and p.is_file():
        try:
            keys = set(npz_names(p, "dataset", NPZ_HINT, DatasetError))
        except DatasetError:
            return False  # the dataset loaders say what is wrong with it
        return "class_names" in keys and any(k.startswith("y_") and "X_" + k[2:] in keys for k in keys)
    return False


def load_recordings(path: str | Path) -> RecordingSet:
    """Load a folder of labelled CSV recordings or a continuous .npz; clear errors otherwise."""
    p = Path(path).expanduser()
    if not p.exists():
        raise DatasetError(f"{p} does not exist")
    if p.is_dir():
        return _load_csv_folder(p)
    return _load_npz(read_npz(p, "continuous dataset", NPZ_HINT, DatasetError), str(p))


def _load_npz(arrays: dict[str, np.ndarray], source: str) -> RecordingSet:
    if "class_names" not in arrays:
        raise DatasetError(f"{source}: a continuous .npz needs a 'class_names' array")
    names = [str(c) for c in np.atleast_1d(arrays["class_names"])]
    recs = []
    for key in sorted(arrays):
        if not key.startswith("X_"):
            continue
        name = key[2:]
        if "y_" + name not in arrays:
            raise DatasetError(f"{source}: '{key}' has no label array 'y_{name}'")
        X = np.asarray(arrays[key])
        y = np.asarray(arrays["y_" + name])
        if X.ndim != 2 or not np.issubdtype(X.dtype, np.number):
            raise DatasetError(f"{source}: '{key}' must be a numeric (T, D) array, got shape {X.shape} {X.dtype}")
        if y.ndim != 1 or len(y) != len(X) or not np.issubdtype(y.dtype, np.integer):
            raise DatasetError(f"{source}: 'y_{name}' must hold one integer label per row of '{key}' ({len(X)})")
        if ((y < UNLABELLED) | (y >= len(names))).any():
            raise DatasetError(f"{source}: 'y_{name}' holds indices outside -1…{len(names) - 1} (class_names)")
        recs.append(Recording(name, X.astype(float), y.astype(int)))
    if not recs:
        raise DatasetError(f"{source}: no 'X_<name>'/'y_<name>' pairs found")
    unknown = [str(c) for c in np.atleast_1d(arrays.get("unknown_classes", np.array([], dtype=str)))]
    if not set(unknown) <= set(names):
        raise DatasetError(f"{source}: 'unknown_classes' {unknown} must be among class_names {names}")
    return RecordingSet(recs, names, [f"x{i}" for i in range(recs[0].X.shape[1])], source, unknown)


def _read_labelled_csv(path: Path) -> tuple[list[str], np.ndarray, list[str]]:
    with path.open(newline="") as f:
        rows = [r for r in csv.reader(f) if r]
    if len(rows) < 2:
        raise DatasetError(f"{path} needs a header row and at least one data row")
    header = [h.strip() for h in rows[0]]
    if header[-1].lower() != LABEL_COLUMN:
        raise DatasetError(f"{path}: the last column must be '{LABEL_COLUMN}' (class name per row), got '{header[-1]}'")
    values, labels = [], []
    for n, r in enumerate(rows[1:], start=2):
        if len(r) != len(header):
            raise DatasetError(f"{path}:{n}: {len(r)} values, the header has {len(header)}")
        try:
            values.append([float(v) for v in r[:-1]])
        except ValueError as exc:
            raise DatasetError(f"{path}:{n}: non-numeric feature value ({exc})") from None
        labels.append(r[-1].strip())
    X = np.array(values, dtype=float).reshape(len(values), len(header) - 1)
    cols = header[:-1]
    keep = [i for i, h in enumerate(cols) if h.lower() not in TIME_COLUMNS]
    return [cols[i] for i in keep], X[:, keep], labels


def _load_csv_folder(root: Path) -> RecordingSet:
    files = sorted(root.glob("*.csv"))
    if not files:
        raise DatasetError(f"{root} holds no .csv recordings")
    parsed = [(f, *_read_labelled_csv(f)) for f in files]
    columns = parsed[0][1]
    names = sorted({lab for *_, labels in parsed for lab in labels if lab})
    index = {c: k for k, c in enumerate(names)}
    recs = []
    for f, cols, X, labels in parsed:
        if cols != columns:
            raise DatasetError(f"{f}: columns {cols} differ from {columns} of {files[0].name}")
        y = np.array([index[lab] if lab else UNLABELLED for lab in labels], dtype=int)
        recs.append(Recording(f.stem, X, y))
    return RecordingSet(recs, names, columns, str(root))


def _check(rs: RecordingSet) -> None:
    dims = {r.X.shape[1] for r in rs.recordings}
    if len(dims) != 1:
        raise DatasetError(f"all recordings must have the same number of feature columns, found {sorted(dims)}")
    for r in rs.recordings:
        if len(r.X) < 2:
            raise DatasetError(f"recording '{r.name}' must hold at least 2 rows")
        bad = ~np.isfinite(r.X).all(axis=1)
        if bad.any():
            raise DatasetError(
                f"recording '{r.name}' holds NaN/inf in row {int(np.flatnonzero(bad)[0])}; "
                "fill or drop such rows before evaluating"
            )
    if len({r.name for r in rs.recordings}) != len(rs.recordings):
        raise DatasetError("recording names must be unique")


def basicmotions_continuous(
    path: str | Path, n_recordings: int = 8, seed: int = 0, cases: int | None = None
) -> dict[str, np.ndarray]:
    """BasicMotions as continuous recordings: all train + test cases shuffled with ``seed`` and
    concatenated into ``n_recordings`` recordings (80 cases → 8 × 10); arrays in the .npz layout.
    ``cases``: that many cases drawn with replacement instead (seeded; the cost's growth with the
    recordings' length, docs/benchmarks.md)."""
    path = Path(path).expanduser()
    d = read_npz(path, "UEA dataset", "pass ../shared/data/basicmotions.npz or the same layout", DatasetError)
    with building(
        path, "UEA dataset", "it needs X_train, X_test, labels_train, labels_test, class_names", DatasetError
    ):
        X = np.concatenate([d["X_train"], d["X_test"]])  # (cases, channels, time)
        y = np.concatenate([d["labels_train"], d["labels_test"]]).astype(int)
        names = [str(c) for c in d["class_names"]]
        if X.ndim != 3 or len(y) != len(X) or not 0 <= y.min() <= y.max() < len(names):
            raise ValueError(f"cases {X.shape}, labels {y.shape} and {len(names)} class names disagree")
        if (cases or len(X)) < n_recordings:
            raise ValueError(f"{cases or len(X)} cases cannot fill {n_recordings} recordings")
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(X)) if cases is None else rng.integers(0, len(X), cases)
    out: dict[str, np.ndarray] = {"class_names": np.array(names)}
    for k, part in enumerate(np.array_split(order, n_recordings)):
        out[f"X_rec{k}"] = np.concatenate([X[i].T for i in part])
        out[f"y_rec{k}"] = np.concatenate([np.full(X.shape[2], y[i]) for i in part])
    return out
