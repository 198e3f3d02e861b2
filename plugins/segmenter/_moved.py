"""The module paths of the flat layout before the sub-packages, kept for one release.

``import handflow.plugins.segmenter.clm_segmenter`` (and every other moved path) still works: a
finder on ``sys.meta_path`` answers it with a module that forwards every attribute to the module's
new home (then to :mod:`.base`, where ``REJECTED`` and ``runs`` went) and warns with a
``DeprecationWarning`` naming the path to import from instead.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings
from pathlib import Path

MOVED = {  # old module -> its new home (private module, or the sub-package of a module split up)
    "scaling": "features._scaling",
    "running_scaling": "features._running_scaling",
    "delay": "features._delay",
    "derived": "features._derived",
    "headings": "features._headings",
    "intensity": "novelty._intensity",
    "feature_novelty": "novelty._feature_novelty",
    "training": "models._training",
    "cycles": "models._cycles",
    "candidates": "models._candidates",
    "fast_projection": "models._fast_projection",
    "clm_segmenter": "clm._segmenter",
    "ukr_only": "clm._ukr_only",
    "online_scores": "online._scores",
    "baselines": "scorers",  # split: DTW, HMM and what they share
    "continuous": "datasets._recordings",
    "synthetic": "datasets._synthetic",
    "openset": "evaluation._metrics",
    "frame_methods": "evaluation._methods",
    "stream_evaluation": "evaluation._recordings",
    "stream_cli": "cli._recordings",
}
_PACKAGE = str(Path(__file__).parent)
_FORWARDERS = (_PACKAGE, importlib.__file__)  # frames between the importer and the finder


def _importer_level() -> int:
    """The ``stacklevel`` that points a warning at the import line of the caller: past this package
    and the import machinery (whose frames ``warnings`` skips by itself)."""
    level, frame = 1, sys._getframe(2)
    while frame is not None:
        name = frame.f_code.co_filename
        if not ("importlib" in name and "_bootstrap" in name):
            level += 1
            if not name.startswith(_FORWARDERS):
                break
        frame = frame.f_back
    return level


class _MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def __init__(self, package: str) -> None:
        self.package = package

    def find_spec(self, fullname, path, target=None):
        parent, _, name = fullname.rpartition(".")
        if parent != self.package or name not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        return None

    def exec_module(self, module: types.ModuleType) -> None:
        new = MOVED[module.__name__.rpartition(".")[2]]
        public = f"{self.package}.{new.partition('.')[0]}"
        message = f"{module.__name__} is deprecated and goes in the next release: import from {public}"
        warnings.warn(message, DeprecationWarning, stacklevel=_importer_level())
        homes = [importlib.import_module(f"{self.package}.{m}") for m in (new, "base")]

        def forward(name: str):
            for home in homes:
                try:
                    return getattr(home, name)
                except AttributeError:
                    pass
            raise AttributeError(f"module {module.__name__!r} has no attribute {name!r}")

        module.__getattr__ = forward
        module.__dir__ = lambda: sorted({n for home in homes for n in dir(home)})


def install(package: str) -> None:
    """Answer the moved module paths of ``package`` (once per interpreter)."""
    if not any(isinstance(f, _MovedModules) and f.package == package for f in sys.meta_path):
        sys.meta_path.append(_MovedModules(package))


def renamed(module: str, names: dict[str, str]):
    """A module ``__getattr__`` that answers each old name in ``names`` (old → new) with the object
    of its new name, warning with a ``DeprecationWarning`` that names the new one."""
    namespace = sys.modules[module].__dict__

    def __getattr__(name: str):
        if name not in names:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        warnings.warn(
            f"{name} is deprecated and goes in the next release: use {names[name]}", DeprecationWarning, stacklevel=2
        )
        return namespace[names[name]]

    return __getattr__
