"""Structured UKR manifolds (docs/training.md): plain numpy/scipy, independent of the runtime."""

from .model import StructuredUKR
from .validation import InvalidInputError, LatentDim

__all__ = ["StructuredUKR", "InvalidInputError", "LatentDim"]
