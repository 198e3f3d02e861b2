"""The method registry of both evaluation protocols (docs/segmentation.md): every recogniser by
its name, as a frame labeller for continuous recordings and, where the trajectory protocol runs
it, as a labeller of the trajectory cases (:data:`REGISTRY`); the methods themselves live in
:mod:`._method_base`, :mod:`._score_methods`, :mod:`._manifold_methods` and :mod:`._clm_methods`.

Each method declares the modules it needs beyond the core (``requires``, as a node does);
:func:`methods_to_run` checks them before an evaluation computes anything.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterable

from handflow.framework.files.inputs import missing_modules

from ._clm_methods import NoveltyCLMMethod, ScoreCLMMethod
from ._manifold_methods import (
    MAX_FIT_RATIOS,
    MIN_PROGRESS,
    MIN_SPANS,
    UKRCLMMethod,
    UKRCLMOnlineMethod,
    UKRMethod,
    UKROnlyMethod,
)
from ._method_base import Fitted, Method, ScoreMethod, ThresholdOnTrajectories
from ._score_methods import DTWMethod, HMMMethod, MiniRocketMethod

__all__ = [
    "MAX_FIT_RATIOS",
    "MIN_PROGRESS",
    "MIN_SPANS",
    "DTWMethod",
    "Fitted",
    "HMMMethod",
    "Method",
    "MiniRocketMethod",
    "NoveltyCLMMethod",
    "ScoreCLMMethod",
    "ScoreMethod",
    "ThresholdOnTrajectories",
    "UKRCLMMethod",
    "UKRCLMOnlineMethod",
    "UKRMethod",
    "UKROnlyMethod",
    "REGISTRY",
    "METHODS",
    "TRAJECTORY_METHODS",
    "missing_extras",
    "methods_to_run",
]

_UKR_CLM = UKRCLMMethod()
REGISTRY: dict[str, Method] = {
    m.name: m
    for m in (
        UKROnlyMethod(),
        _UKR_CLM,
        DTWMethod(),
        HMMMethod(),
        UKRCLMOnlineMethod(_UKR_CLM),
        MiniRocketMethod(),
        ScoreCLMMethod(MiniRocketMethod()),
        ScoreCLMMethod(DTWMethod()),
        NoveltyCLMMethod(MiniRocketMethod(feature_novelty=True)),
        NoveltyCLMMethod(DTWMethod()),
    )
}
METHODS = REGISTRY  # the name of the flat layout
TRAJECTORY_METHODS = tuple(name for name, m in REGISTRY.items() if m.on_trajectories)


def missing_extras(names: Iterable[str]) -> dict[str, str]:
    """Method → what to install, for the registry methods of ``names`` whose extra is missing."""
    return {name: "; ".join(why) for name in names if (why := missing_modules(REGISTRY[name].requires))}


def methods_to_run(
    option: str | None, default: tuple[str, ...], allowed: Collection[str], progress: Callable[[str], None]
) -> tuple[tuple[str, ...], dict[str, str]]:
    """The methods an evaluation runs and those it skips (method → what to install), before it
    computes anything (docs/segmentation.md, "Methods and their extras"): the comma-separated
    ``option`` (``--methods``) as given — a ValueError when a name is unknown or its extra is
    missing — or, without it, those of ``default`` whose extras are installed."""
    if not option:
        skipped = missing_extras(default)
        for name, why in skipped.items():
            progress(f"skipping {name}: it {why}")
        return tuple(m for m in default if m not in skipped), skipped
    names = tuple(m for m in option.split(",") if m)
    unknown = sorted(set(names) - set(allowed))
    if unknown:
        raise ValueError(f"unknown method(s) {unknown}; choose from {list(allowed)}")
    missing = missing_extras(names)
    if missing:
        raise ValueError(
            "; ".join(f"method {name} {why}" for name, why in missing.items()) + " (or leave it out of --methods)"
        )
    return names, {}
