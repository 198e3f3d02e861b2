"""Motion recognition and segmentation with structured manifolds (docs/segmentation.md).

Usable without the runtime: load a dataset, train one manifold per class, recognise.

>>> ds = load_dataset("letters.npz")                       # doctest: +SKIP
>>> cands = candidate_set(train_class_models(ds))          # doctest: +SKIP
>>> CLMSegmenter(cands, history=10).fit_predict(Y)         # doctest: +SKIP
"""

from .baselines import PerClassHMM, SlidingDTW1NN
from .candidates import CandidateModel, CandidateSet, ModelsMissingError, Projection, UKRCandidate, load_candidates
from .clm import CLMResult, CompetitiveLayerModel, clm_energy
from .clm_segmenter import CLMSegmenter
from .datasets import DatasetError, LabelledDataset, Trajectory, load_dataset
from .evaluation import EXPERIMENTS, METHODS, Evaluator, Protocol
from .online import OnlineCLMSegmenter, OnlineUpdate, SegmentChange
from .synthetic import LetterGenerator
from .training import candidate_set, save_class_models, train_class_models
from .ukr_only import UKROnlyRecognizer

__all__ = [
    "CandidateModel",
    "CandidateSet",
    "CLMResult",
    "CLMSegmenter",
    "CompetitiveLayerModel",
    "DatasetError",
    "EXPERIMENTS",
    "Evaluator",
    "LabelledDataset",
    "LetterGenerator",
    "METHODS",
    "ModelsMissingError",
    "OnlineCLMSegmenter",
    "OnlineUpdate",
    "PerClassHMM",
    "Projection",
    "Protocol",
    "SegmentChange",
    "SlidingDTW1NN",
    "Trajectory",
    "UKRCandidate",
    "UKROnlyRecognizer",
    "candidate_set",
    "clm_energy",
    "load_candidates",
    "load_dataset",
    "save_class_models",
    "train_class_models",
]
