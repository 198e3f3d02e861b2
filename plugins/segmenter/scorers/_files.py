"""Scorer files (docs/segmentation.md, "Score sources"): the kinds a file may hold and the loader,
which never unpickles and checks version, checksums and shapes."""

from __future__ import annotations

import math
from pathlib import Path

from handflow.framework.files.npz import building, npz_metadata, read_npz

from ._dtw import DTWScorer
from ._minirocket import MiniRocketScorer
from ._window import FORMAT, FORMAT_VERSION, ScorerFileError, WindowScorer, _digest

SCORERS: dict[str, type[WindowScorer]] = {"minirocket": MiniRocketScorer, "dtw": DTWScorer}


def load_scorer(path: str | Path) -> WindowScorer:
    """Read a scorer written by :meth:`WindowScorer.save`; :class:`ScorerFileError` on any bad file."""
    path = Path(path)
    refit = "fit a new one with `handflow fit-scorer` (docs/segmentation.md)"
    arrays = read_npz(path, "scorer", refit, ScorerFileError)
    meta = _metadata(path, arrays, refit)
    arrays.pop("metadata")
    cls = SCORERS[meta["kind"]]
    for name, digest in meta["sha256"].items():
        if name not in arrays or _digest(arrays[name]) != digest:
            raise ScorerFileError(f"{path}: array '{name}' is missing or changed since it was saved; {refit}")
    if set(arrays) != set(meta["sha256"]):
        raise ScorerFileError(f"{path}: unexpected arrays {sorted(set(arrays) - set(meta['sha256']))}; {refit}")
    with building(path, f"{meta['kind']} scorer", refit, ScorerFileError):
        scorer = cls(**meta["params"])
        scorer.classes_ = list(meta["classes"])
        scorer.n_features_in_ = int(meta["n_features_in"])
        scorer.temperature_ = float(meta["temperature"])
        scorer.null_score_ = float(meta["null_score"]) if "null_score" in meta else None
        scorer.null_calibration_ = meta.get("null_calibration")
        if not (scorer.classes_ and scorer.n_features_in_ >= 1 and scorer.temperature_ > 0 and int(scorer.window) >= 1):
            raise ValueError("classes, channels, temperature or window out of range")
        scorer._restore(arrays)
    return scorer


def _metadata(path: Path, arrays: dict, refit: str) -> dict:
    meta = npz_metadata(arrays, path, "scorer", refit, ScorerFileError, (FORMAT, FORMAT_VERSION, "version"))
    kinds = {"kind": str, "params": dict, "classes": list, "sha256": dict}
    if any(not isinstance(meta.get(k), t) for k, t in kinds.items()) or meta["kind"] not in SCORERS:
        raise ScorerFileError(f"{path}: scorer metadata lacks or garbles kind/params/classes/sha256; {refit}")
    if not all(isinstance(v, str) for v in meta["sha256"].values()):
        raise ScorerFileError(f"{path}: scorer metadata garbles the checksums; {refit}")
    null = meta.get("null_score", 0.0)  # files without it: the null class is not calibrated
    if isinstance(null, bool) or not isinstance(null, int | float) or math.isnan(null):
        raise ScorerFileError(f"{path}: scorer metadata garbles null_score (not a number); {refit}")
    if not isinstance(meta.get("null_calibration", {}), dict):
        raise ScorerFileError(f"{path}: scorer metadata garbles null_calibration; {refit}")
    return meta
