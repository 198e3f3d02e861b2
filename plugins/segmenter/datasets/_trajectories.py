"""Class-labelled trajectory datasets: loading and the documented splits (docs/segmentation.md).

Accepted formats (:func:`load_dataset`):

1. **Folder** with ``train/``, ``validation/`` and ``test/`` sub-folders, each holding CSV files
   ``<label>_<anything>.csv`` — one ordered trajectory per file, a header row, numeric columns.
   A column named ``time``, ``t``, ``timestamp`` or ``stamp`` (any case) is an optional time
   column: rows are sorted by it and it is dropped.  The label is the file-name part before the
   first underscore (so labels cannot contain ``_``).
2. **Labelled .npz** with arrays ``<label>_<k>`` (each (T, d)), e.g. the shared
   ``letters_other_xy.npz``.  There is no split in the file, so :func:`split_counts` defines a
   deterministic one per class, in ascending ``k``: the last ``n_test`` samples are test, the
   ``n_val`` before them validation, the rest training.  With 5 samples per class (letters) that
   is 3 train / 1 validation / 1 test; with 15 it is the thesis' 5/5/5.  When the file's
   ``metadata`` JSON marks a pen-lift tail (``samples[key].pen_lift_start``) it is cut off unless
   ``trim_pen_lift=False``.
3. **UEA-style .npz** (``X_train``, ``labels_train``, ``X_test``, ``labels_test``,
   ``class_names``; ``X`` laid out (cases, channels, time)), e.g. ``basicmotions.npz``.  Test is
   the file's test set; per class, the first half of the training cases (file order, rounded up)
   stay training and the second half becomes validation.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from handflow.framework.files.npz import building, read_npz

SPLITS = ("train", "validation", "test")
TIME_COLUMNS = ("time", "t", "timestamp", "stamp")
NPZ_HINT = "write it with numpy.savez in one of the layouts of docs/segmentation.md"


class DatasetError(ValueError):
    """A dataset that cannot be used; the message says what to change."""


@dataclass
class Trajectory:
    """One ordered trajectory ``data`` (T, d) of class ``label``; ``name`` identifies its source."""

    label: str
    data: np.ndarray
    name: str = ""


@dataclass
class LabelledDataset:
    """Train / validation / test lists of :class:`Trajectory`; ``columns`` names the dimensions."""

    train: list[Trajectory]
    validation: list[Trajectory]
    test: list[Trajectory]
    columns: list[str] = field(default_factory=list)
    source: str = ""

    @property
    def classes(self) -> list[str]:
        """Sorted class labels of the training split."""
        return sorted({t.label for t in self.train})

    def split(self, name: str) -> list[Trajectory]:
        if name not in SPLITS:
            raise DatasetError(f"split must be one of {SPLITS}, got {name!r}")
        return getattr(self, name)

    def by_class(self, name: str) -> dict[str, list[np.ndarray]]:
        """Trajectories of one split grouped by label (labels sorted)."""
        out: dict[str, list[np.ndarray]] = {}
        for t in sorted(self.split(name), key=lambda t: t.label):
            out.setdefault(t.label, []).append(t.data)
        return out

    def restrict(self, classes: list[str]) -> LabelledDataset:
        """The same dataset with only the given classes."""
        missing = sorted(set(classes) - set(self.classes))
        if missing:
            raise DatasetError(f"classes {missing} are not in the dataset (it has {self.classes})")
        keep = set(classes)
        return LabelledDataset(
            *[[t for t in self.split(s) if t.label in keep] for s in SPLITS], columns=self.columns, source=self.source
        )


def split_counts(n: int) -> tuple[int, int, int]:
    """Deterministic (train, validation, test) counts for ``n`` samples of one class.

    ``n ≥ 9``: a third each for validation and test (rounded down), the rest training;
    ``3 ≤ n < 9``: one validation, one test, the rest training.
    """
    if n < 3:
        raise DatasetError(f"a class needs at least 3 samples to split into train/validation/test, got {n}")
    held = n // 3 if n >= 9 else 1
    return n - 2 * held, held, held


def load_dataset(path: str | Path, trim_pen_lift: bool = True) -> LabelledDataset:
    """Load a dataset folder or .npz (see the module docstring for the formats)."""
    p = Path(path).expanduser()
    if not p.exists():
        raise DatasetError(
            f"dataset {p} does not exist; pass a folder with train/validation/test "
            "sub-folders of <label>_<anything>.csv files or an .npz file"
        )
    if p.is_dir():
        ds = _load_folder(p)
        _check(ds)
    elif p.suffix == ".npz":
        arrays = read_npz(p, "dataset", NPZ_HINT, DatasetError)
        with building(p, "dataset", NPZ_HINT, DatasetError):
            ds = _load_uea(arrays) if "X_train" in arrays else _load_labelled_npz(arrays, trim_pen_lift)
            _check(ds)
    else:
        raise DatasetError(f"dataset {p} is neither a folder nor an .npz file")
    ds.source = str(p)
    return ds


def _check(ds: LabelledDataset) -> None:
    dims = {t.data.shape[1] for s in SPLITS for t in ds.split(s)}
    if len(dims) != 1:
        raise DatasetError(f"all trajectories must have the same number of columns, found {sorted(dims)}")
    for s in SPLITS:
        if not ds.split(s):
            raise DatasetError(f"the {s} split is empty")
        for t in ds.split(s):
            if t.data.shape[0] < 2 or not np.isfinite(t.data).all():
                raise DatasetError(f"trajectory {t.name} must hold >= 2 finite rows, got shape {t.data.shape}")
    unseen = {t.label for s in ("validation", "test") for t in ds.split(s)} - set(ds.classes)
    if unseen:
        raise DatasetError(f"labels {sorted(unseen)} occur in validation/test but not in train")


def _label_of(stem: str) -> str:
    label, sep, _ = stem.partition("_")
    if not sep or not label:
        raise DatasetError(f"file/array name {stem!r} must look like <label>_<anything>")
    return label


def _read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    if len(rows) < 2:
        raise DatasetError(f"{path} needs a header row and at least one data row")
    header = [h.strip() for h in rows[0]]
    try:
        data = np.array([[float(v) for v in r] for r in rows[1:] if r], dtype=float)
    except ValueError as exc:
        raise DatasetError(f"{path}: non-numeric value ({exc}); only the header row may hold text") from None
    if data.ndim != 2 or data.shape[1] != len(header):
        raise DatasetError(f"{path}: every row must have {len(header)} values like the header")
    time_cols = [i for i, h in enumerate(header) if h.lower() in TIME_COLUMNS]
    if time_cols:
        data = data[np.argsort(data[:, time_cols[0]], kind="stable")]
        keep = [i for i in range(len(header)) if i not in time_cols]
        header, data = [header[i] for i in keep], data[:, keep]
    return header, data


def _load_folder(root: Path) -> LabelledDataset:
    missing = [s for s in SPLITS if not (root / s).is_dir()]
    if missing:
        raise DatasetError(
            f"dataset folder {root} lacks the sub-folder(s) {missing}; it needs train/, validation/ and test/"
        )
    splits, columns = {}, None
    for s in SPLITS:
        trajs = []
        for f in sorted((root / s).glob("*.csv")):
            header, data = _read_csv(f)
            if columns is not None and header != columns:
                raise DatasetError(f"{f}: header {header} differs from {columns}")
            columns = header
            trajs.append(Trajectory(_label_of(f.stem), data, f"{s}/{f.name}"))
        splits[s] = trajs
    return LabelledDataset(splits["train"], splits["validation"], splits["test"], columns=columns or [])


def _load_labelled_npz(arrays: dict[str, np.ndarray], trim_pen_lift: bool) -> LabelledDataset:
    meta = json.loads(str(arrays.pop("metadata"))) if "metadata" in arrays else {}
    samples = meta.get("samples", {}) if isinstance(meta, dict) else {}
    groups: dict[str, list[tuple[str, str]]] = {}
    for key in arrays:
        label, _, rest = key.partition("_")
        _label_of(key)
        groups.setdefault(label, []).append((rest, key))
    splits: dict[str, list[Trajectory]] = {s: [] for s in SPLITS}
    for label, items in sorted(groups.items()):
        items.sort(key=lambda it: (int(it[0]) if it[0].isdigit() else 0, it[0]))
        n_train, n_val, _ = split_counts(len(items))
        for i, (_, key) in enumerate(items):
            data = np.asarray(arrays[key], dtype=float)
            if data.ndim == 1:
                data = data[:, None]
            cut = samples.get(key, {}).get("pen_lift_start") if trim_pen_lift else None
            if cut:
                data = data[: int(cut)]
            s = "train" if i < n_train else "validation" if i < n_train + n_val else "test"
            splits[s].append(Trajectory(label, data, key))
    dim = next(iter(splits["train"])).data.shape[1] if splits["train"] else 0
    columns = meta.get("columns") if isinstance(meta.get("columns"), list) else [f"y{i}" for i in range(dim)]
    return LabelledDataset(splits["train"], splits["validation"], splits["test"], columns=columns)


def _load_uea(arrays: dict[str, np.ndarray]) -> LabelledDataset:
    needed = {"X_train", "labels_train", "X_test", "labels_test"}
    if not needed <= set(arrays):
        raise DatasetError(f"a UEA-style .npz needs arrays {sorted(needed)}; it has {sorted(arrays)}")
    names = [str(c) for c in arrays["class_names"]] if "class_names" in arrays else None

    def trajectories(part: str) -> list[Trajectory]:
        X, y = arrays[f"X_{part}"], arrays[f"labels_{part}"]
        return [
            Trajectory(names[int(c)] if names else str(c), np.asarray(x, dtype=float).T, f"{part}[{i}]")
            for i, (x, c) in enumerate(zip(X, y))
        ]

    train, validation = [], []
    full = trajectories("train")
    for label in sorted({t.label for t in full}):
        members = [t for t in full if t.label == label]
        half = (len(members) + 1) // 2
        train += members[:half]
        validation += members[half:]
    channels = [str(c) for c in arrays["channel_names"]] if "channel_names" in arrays else []
    return LabelledDataset(train, validation, trajectories("test"), columns=channels)
