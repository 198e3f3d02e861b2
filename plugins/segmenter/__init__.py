"""Motion recognition and segmentation with structured manifolds (docs/segmentation.md).

Usable without the runtime: load a dataset, train one manifold per class, recognise.

>>> ds = load_dataset("letters.npz")                       # doctest: +SKIP
>>> cands = candidate_set(train_class_models(ds))          # doctest: +SKIP
>>> CLMSegmenter(cands, history=10).fit_predict(Y)         # doctest: +SKIP

The sub-packages group the parts by concept (docs/architecture.md); the module paths of the
flat layout before them still import, with a ``DeprecationWarning`` naming the new path
(:mod:`._moved`).
"""

import importlib

from ._moved import MOVED, install

_SOURCES = {
    "CLMResult": "clm",
    "CLMSegmenter": "clm",
    "CandidateModel": "models",
    "CandidateSet": "models",
    "CompetitiveLayerModel": "clm",
    "DatasetError": "datasets",
    "EXPERIMENTS": "evaluation",
    "Evaluator": "evaluation",
    "LabelledDataset": "datasets",
    "LetterGenerator": "datasets",
    "METHODS": "evaluation",
    "ModelsMissingError": "models",
    "OnlineCLMSegmenter": "online",
    "OnlineUpdate": "online",
    "PerClassHMM": "scorers",
    "Projection": "models",
    "Protocol": "evaluation",
    "SegmentChange": "online",
    "SlidingDTW1NN": "scorers",
    "Trajectory": "datasets",
    "TrajectoryProtocol": "evaluation",
    "UKRCandidate": "models",
    "UKROnlyRecognizer": "clm",
    "candidate_set": "models",
    "clm_energy": "clm",
    "load_candidates": "models",
    "load_dataset": "datasets",
    "save_class_models": "models",
    "train_class_models": "models",
}

__all__ = sorted(set(_SOURCES) - {"Protocol"})  # Protocol: deprecated name of TrajectoryProtocol

install(__name__)


def __getattr__(name: str):
    """Import the sub-package that defines ``name`` on first use (a node loads only what it needs)."""
    if name in MOVED:
        return importlib.import_module(f"{__name__}.{name}")
    if name not in _SOURCES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f".{_SOURCES[name]}", __name__), name)
