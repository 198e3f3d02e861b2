"""Motion recognition and segmentation with structured manifolds (docs/segmentation.md).

Usable without the runtime: load a dataset, train one manifold per class, recognise.

>>> ds = load_dataset("letters.npz")                       # doctest: +SKIP
>>> cands = candidate_set(train_class_models(ds))          # doctest: +SKIP
>>> CLMSegmenter(cands, history=10).fit_predict(Y)         # doctest: +SKIP
"""

import importlib

_SOURCES = {
    "CLMResult": "clm",
    "CLMSegmenter": "clm_segmenter",
    "CandidateModel": "candidates",
    "CandidateSet": "candidates",
    "CompetitiveLayerModel": "clm",
    "DatasetError": "datasets",
    "EXPERIMENTS": "evaluation",
    "Evaluator": "evaluation",
    "LabelledDataset": "datasets",
    "LetterGenerator": "synthetic",
    "METHODS": "evaluation",
    "ModelsMissingError": "candidates",
    "OnlineCLMSegmenter": "online",
    "OnlineUpdate": "online",
    "PerClassHMM": "baselines",
    "Projection": "candidates",
    "Protocol": "evaluation",
    "SegmentChange": "online",
    "SlidingDTW1NN": "baselines",
    "Trajectory": "datasets",
    "UKRCandidate": "candidates",
    "UKROnlyRecognizer": "ukr_only",
    "candidate_set": "training",
    "clm_energy": "clm",
    "load_candidates": "candidates",
    "load_dataset": "datasets",
    "save_class_models": "training",
    "train_class_models": "training",
}

__all__ = sorted(_SOURCES)


def __getattr__(name: str):
    """Import the module that defines ``name`` on first use (a node loads only what it needs)."""
    if name not in _SOURCES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f".{_SOURCES[name]}", __name__), name)
