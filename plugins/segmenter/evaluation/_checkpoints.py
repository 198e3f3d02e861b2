"""Finished folds of a leave-one-recording-out evaluation kept on disk, so that a long evaluation
survives an interruption and resumes where it stopped (docs/segmentation.md, ``--checkpoints``).

Each fold is written as ``fold-<recording>.npz`` when it ends (atomically: a stopped run leaves
no half-written fold): its arrays, and a JSON ``metadata`` string with the rest of the fold and
the *digest* of what the fold depends on — the recordings' contents, the evaluation's settings,
the handflow version and the source of the packages that compute it (the segmenter's and the
manifolds'; an edited editable install is other code).  A later run with the same digest takes the fold from the file; a file
of other settings or data, of another format version, or one that cannot be read is computed
again, and the progress says why.  Files are never unpickled.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np

from handflow.framework.files.npz import NpzFileError, building, npz_metadata, read_npz
from handflow.framework.files.provenance import installed_version

FORMAT = "handflow.evaluation-fold"
FORMAT_VERSION = 1
UNSAFE = re.compile(r"[^\w.-]")  # characters a recording's name may not bring into a file name
_ARRAY = "@array"  # a JSON object {"@array": key} stands for the file's array ``key``


def _code(h) -> None:
    """Feed ``h`` the source files of the packages whose code computes a fold."""
    import handflow.plugins.manifold as manifold

    for root in (Path(__file__).parents[1], Path(manifold.__file__).parent):
        for path in sorted(root.rglob("*.py")):
            h.update(path.relative_to(root).as_posix().encode())
            h.update(path.read_bytes())


def settings_digest(recordings: list, class_names: list[str], settings: dict) -> str:
    """SHA-256 of the recordings' names, samples and labels, the class names, ``settings``
    (JSON-able), the handflow version and the code: what a fold's figures depend on."""
    h = hashlib.sha256()
    _code(h)
    for r in recordings:
        for part in (
            r.name.encode(),
            np.ascontiguousarray(r.X, dtype=float),
            np.ascontiguousarray(r.y, dtype=np.int64),
        ):
            h.update(part if isinstance(part, bytes) else part.tobytes())
    h.update(json.dumps([class_names, settings, installed_version()], sort_keys=True, default=str).encode())
    return h.hexdigest()


def _flatten(value, arrays: dict[str, np.ndarray]):
    """``value`` as JSON, each array replaced by a reference to an entry of ``arrays``."""
    if isinstance(value, np.ndarray):
        key = f"a{len(arrays)}"
        arrays[key] = value
        return {_ARRAY: key}
    if isinstance(value, dict):
        return {str(k): _flatten(v, arrays) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_flatten(v, arrays) for v in value]
    return value.item() if isinstance(value, np.generic) else value


def _restore(value, arrays: dict[str, np.ndarray]):
    if isinstance(value, dict):
        if set(value) == {_ARRAY}:
            return arrays[value[_ARRAY]]
        return {k: _restore(v, arrays) for k, v in value.items()}
    if isinstance(value, list):
        return [_restore(v, arrays) for v in value]
    return value


class FoldCheckpoints:
    """The finished folds (dataclass instances of ``fold_type``) of one evaluation in ``directory``."""

    def __init__(self, directory: str | Path, digest: str, fold_type: type, progress: Callable[[str], None]) -> None:
        self.directory = Path(directory).expanduser()
        self.digest = digest
        self.fold_type = fold_type
        self.progress = progress

    def path(self, held: str) -> Path:
        return self.directory / f"fold-{UNSAFE.sub('_', held)}.npz"

    def load(self, held: str):
        """The fold of ``held`` from its file, or None (no file, or one that cannot be used here)."""
        path = self.path(held)
        if not path.exists():
            return None
        hint = "the fold is computed again"
        try:
            arrays = read_npz(path, "evaluation fold", hint)
            meta = npz_metadata(arrays, path, "evaluation fold", hint, fmt=(FORMAT, FORMAT_VERSION, "version"))
            if meta.get("digest") != self.digest:
                self.progress(f"  {path}: a fold of other recordings, settings or code; computing it again")
                return None
            with building(path, "evaluation fold", hint):
                fold = self.fold_type(**_restore(meta["fold"], arrays))
                if fold.recording != held:
                    raise ValueError(f"it holds the fold of '{fold.recording}'")
        except NpzFileError as exc:
            self.progress(f"  {exc}")
            return None
        return fold

    def save(self, fold) -> None:
        """Write ``fold`` (atomically: a temporary file renamed into place)."""
        arrays: dict[str, np.ndarray] = {}
        meta = {
            "format": FORMAT,
            "version": FORMAT_VERSION,
            "digest": self.digest,
            "fold": _flatten({f.name: getattr(fold, f.name) for f in dataclasses.fields(fold)}, arrays),
        }
        self.directory.mkdir(parents=True, exist_ok=True)
        path = self.path(fold.recording)
        partial = path.with_name(f".{path.name}.partial")
        with partial.open("wb") as f:
            np.savez(f, metadata=np.array(json.dumps(meta)), **arrays)
        os.replace(partial, path)
