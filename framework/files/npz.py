"""One reader for the ``.npz`` files handflow reads — trained models, manifolds, SOMs, grasp
datasets, scorers, recognition datasets, training data: a missing, truncated, corrupted or foreign
file, or one whose metadata another version wrote, comes back as :class:`NpzFileError` (or the
caller's own ``ValueError`` class) naming the file and what to do (docs/robustness.md).

:func:`read_npz` reads the arrays at once (no pickles), :func:`npz_names` only lists them;
:func:`npz_metadata` parses the JSON
metadata array the writers store; :func:`building` turns the errors of constructing an object
from garbled contents into the same error.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Collection, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np


class NpzFileError(ValueError):
    """A file that cannot be used; the message names it and says what to do."""


ZIP_MAGIC = b"PK"
"""How an .npz archive (a zip file) starts."""


def _starts(head: bytes) -> str:
    return f"this one starts with {head!r}" if head else "this one is empty"


@contextmanager
def _opened(path, what: str, hint: str, error: type[ValueError]) -> Iterator[np.lib.npyio.NpzFile]:
    path = Path(path)
    if not path.is_file():
        raise error(f"{path}: no such {what} file; {hint}")
    with open(path, "rb") as f:
        head = f.read(4)
    if not head.startswith(ZIP_MAGIC):  # numpy would take it for a pickle and advise allow_pickle
        raise error(
            f"{path}: not a {what} file: that is an .npz archive (a zip of NumPy arrays), {_starts(head)}; {hint}"
        )
    try:
        with np.load(path, allow_pickle=False) as data:
            yield data
    except Exception as exc:  # numpy's reader raises many types on a bad file: zipfile, zlib, tokenize, …
        raise error(f"{path}: not a readable {what} file ({type(exc).__name__}: {exc}); {hint}") from None


def read_npz(
    path, what: str, hint: str, error: type[ValueError] = NpzFileError, names: Collection[str] | None = None
) -> dict[str, np.ndarray]:
    """The arrays of the ``what`` file at ``path`` (e.g. "Structured UKR model") — all of them, or
    those of ``names`` it has; ``hint`` says how to make a good one.  Raises ``error`` for a missing
    or unreadable file."""
    with _opened(path, what, hint, error) as data:
        return {k: data[k] for k in data.files if names is None or k in names}


def npz_names(path, what: str, hint: str, error: type[ValueError] = NpzFileError) -> list[str]:
    """The names of the arrays in the file, without reading them; errors as :func:`read_npz`."""
    with _opened(path, what, hint, error) as data:
        return list(data.files)


def npz_metadata(
    arrays: dict[str, np.ndarray],
    path,
    what: str,
    hint: str,
    error: type[ValueError] = NpzFileError,
    fmt: tuple[str, int, str] | None = None,
) -> dict:
    """The JSON object stored in the ``metadata`` array of a file read by :func:`read_npz`;
    ``fmt`` = (format name, format version, key of the version) checks both entries."""
    raw = arrays.get("metadata")
    if raw is None or raw.ndim != 0 or raw.dtype.kind != "U":
        raise error(f"{path}: no {what} metadata (not a file handflow wrote); {hint}")
    try:
        meta = json.loads(str(raw))
    except ValueError:
        raise error(f"{path}: {what} metadata is not valid JSON; {hint}") from None
    if not isinstance(meta, dict):
        raise error(f"{path}: {what} metadata is not a JSON object; {hint}")
    if fmt is not None:
        name, version, key = fmt
        if meta.get("format") != name:
            raise error(f"{path}: not a handflow {what} file (format {meta.get('format')!r}); {hint}")
        if meta.get(key) != version:
            raise error(
                f"{path}: {what} file format version {meta.get(key)!r}, this handflow reads version {version}; {hint}"
            )
    return meta


@contextmanager
def building(path, what: str, hint: str, error: type[ValueError] = NpzFileError) -> Iterator[None]:
    """Turn the errors of building an object from a file's contents (missing or mistyped metadata
    entries, arrays of the wrong shape, the object's own validation) into ``error`` (any
    ``ValueError`` class) naming the file; an :class:`NpzFileError` passes through."""
    try:
        yield
    except NpzFileError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError, OverflowError) as exc:
        raise error(f"{path}: inconsistent {what} file ({type(exc).__name__}: {exc}); {hint}") from None


def format_check(
    what: str, hint: str, fmt: tuple[str, int, str], error: type[ValueError] = NpzFileError
) -> Callable[[Path], None]:
    """A preflight ``check`` for :class:`~handflow.framework.files.inputs.InputPath`: reads only the
    metadata of the ``what`` file and checks its format and version (``fmt`` as in :func:`npz_metadata`)."""

    def check(path: Path) -> None:
        npz_metadata(read_npz(path, what, hint, error, names=("metadata",)), path, what, hint, error, fmt)

    return check
