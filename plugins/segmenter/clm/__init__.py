"""The competitive layer model, the CLM segmenter and the UKR-only recogniser (docs/segmentation.md)."""

from ._segmenter import (
    ETA,
    ETA_HEADED,
    RECONSTRUCTIONS,
    CLMSegmenter,
    default_solver,
    run_stretches,
)
from ._solver import (
    BISECTION_MIN_N,
    LANCZOS_MIN_N,
    CLMResult,
    CLMRun,
    CompetitiveLayerModel,
    clm_energy,
    gershgorin_bound,
    largest_eigenvalue,
)
from ._ukr_only import (
    UKROnlyRecognizer,
)

__all__ = [
    "BISECTION_MIN_N",
    "CLMResult",
    "CLMRun",
    "CLMSegmenter",
    "default_solver",
    "CompetitiveLayerModel",
    "ETA",
    "ETA_HEADED",
    "LANCZOS_MIN_N",
    "RECONSTRUCTIONS",
    "UKROnlyRecognizer",
    "clm_energy",
    "gershgorin_bound",
    "largest_eigenvalue",
    "run_stretches",
]
