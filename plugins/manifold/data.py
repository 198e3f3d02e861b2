"""Loading training sequences: a folder of CSV files, an ``.npz`` of arrays, or an MCAP
recording (one topic, optional time ranges).  Every loader returns ``(sequences, names)``
with ``sequences`` a list of finite ``(n_i, d)`` float arrays in chronological order.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from handflow.framework.files.mcap_reader import read_messages
from handflow.framework.files.npz import read_npz

from .validation import InvalidInputError, check_array


def _exists(path, what):
    p = Path(path)
    if not p.exists():
        raise InvalidInputError(f"{what} {p} does not exist; fix the path in the config")
    return p


def load_csv_dir(path, time_column=None, columns=None):
    """One ordered sequence per ``*.csv`` file (sorted by file name), header row required.

    ``time_column``: dropped from the features; rows are sorted by it (stable).  ``columns``:
    optional list of header names to keep (default: all remaining columns).
    """
    folder = _exists(path, "csv_dir")
    files = sorted(folder.glob("*.csv"))
    if not files:
        raise InvalidInputError(f"csv_dir {folder} contains no *.csv files")
    seqs = []
    for f in files:
        with open(f, newline="") as fh:
            header = [h.strip() for h in next(csv.reader(fh), [])]
        try:
            table = np.loadtxt(f, delimiter=",", skiprows=1, ndmin=2)
        except ValueError as exc:
            raise InvalidInputError(f"{f.name}: not a numeric CSV with one header row ({exc})") from None
        if table.shape[1] != len(header):
            raise InvalidInputError(f"{f.name}: header has {len(header)} names but rows have {table.shape[1]} values")
        keep = [h for h in header if h != time_column] if columns is None else list(columns)
        missing = [c for c in keep + ([time_column] if time_column else []) if c not in header]
        if missing:
            raise InvalidInputError(f"{f.name}: columns {missing} not in header {header}")
        if time_column:
            table = table[np.argsort(table[:, header.index(time_column)], kind="stable")]
        seqs.append(check_array(table[:, [header.index(c) for c in keep]], f.name))
    return seqs, [f.stem for f in files]


def load_npz(path):
    """Every array of the ``.npz`` (in stored order) is one sequence (n_i, d)."""
    p = _exists(path, "npz")
    data = read_npz(p, "training data", "fix the path in the config or rewrite the file", InvalidInputError)
    names, arrays = list(data), list(data.values())
    seqs = [check_array(a.reshape(-1, 1) if a.ndim < 2 else a, f"{p.name}[{k}]") for k, a in zip(names, arrays)]
    if not seqs:
        raise InvalidInputError(f"npz {p} holds no arrays")
    return seqs, names


def load_mcap(path, topic, field="positions", time_ranges=None):
    """Messages of ``topic`` in a recording (either encoding, docs/recording.md); ``field`` names the
    numeric array of the message class (``positions`` of a JointState, ``data`` of an Array).
    ``time_ranges``: list of ``[start_s, end_s]`` in seconds relative to the first message on the
    topic (log time); each range is one sequence; without ranges the whole topic is one sequence.
    """
    p = _exists(path, "mcap")
    times, rows = [], []
    for _, msg, log_time in read_messages(p, topics=[topic]):
        value = getattr(msg, field, None)
        if not isinstance(value, np.ndarray) or not np.issubdtype(value.dtype, np.number):
            arrays = [k for k, v in vars(msg).items() if isinstance(v, np.ndarray)]
            raise InvalidInputError(
                f"{p.name}: a {msg.TYPE} on {topic} has no numeric field {field!r}; set field: to one of {arrays}"
            )
        times.append(log_time)
        rows.append(np.ravel(value.astype(float)))
    if not rows:
        raise InvalidInputError(f"{p.name}: no messages on topic {topic!r}")
    if len({len(r) for r in rows}) > 1:
        raise InvalidInputError(
            f"inconsistent dimensions: messages on {topic} carry {sorted({len(r) for r in rows})} values"
        )
    t = (np.asarray(times) - times[0]) * 1e-9
    Y = check_array(np.vstack(rows), f"{p.name}:{topic}")
    ranges = time_ranges or [[t[0], t[-1]]]
    seqs, names = [], []
    for a, b in ranges:
        sel = (t >= a) & (t <= b)
        if not sel.any():
            raise InvalidInputError(
                f"time range [{a}, {b}] s holds no messages on {topic} (recording spans 0 … {t[-1]:.3f} s)"
            )
        seqs.append(Y[sel])
        names.append(f"{topic}[{a}:{b}]")
    return seqs, names
