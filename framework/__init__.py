"""handflow's framework: files, graphs, network, runtime, recorder, observe, security, testkit (docs/architecture.md).

The modules moved into these parts keep their old paths for one release: importing an old path
gives the new module (or, for a module that was split, a module naming the new homes of its
names) and a ``DeprecationWarning`` naming the new path.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings

# old module → new module(s); a split module lists every new home, first the main one
MOVED: dict[str, tuple[str, ...]] = {
    "npz_files": ("files.npz",),
    "yaml_files": ("files.yaml",),
    "params": ("files.params",),
    "resources": ("files.resources",),
    "recording": ("files.mcap_writer", "files.mcap_reader", "recorder.graph_recorder", "wire"),
    "graph": ("graphs.model", "network.settings"),
    "transport": ("network.sessions", "keys"),
    "launcher": ("runtime.launcher",),
    "runner": ("runtime.runner",),
    "zygote": ("runtime.zygote",),
    "discovery": ("runtime.discovery",),
    "drops": ("runtime.drops",),
    "forwarding": ("runtime.forwarding",),
    "wakeup": ("runtime.wakeup",),
    "ros2.bridge": ("runtime.ros2_bridge",),
    "replay": ("recorder.replay",),
    "monitor": ("observe.monitor",),
    "foxglove_bridge": ("observe.foxglove_bridge",),
    "access": ("security.access",),
    "certs": ("security.certs",),
    "credentials": ("security.credentials",),
    "testing": ("testkit.harness",),
    "fuzzing": ("testkit.fuzzing",),
}


class _SplitModule(types.ModuleType):
    """An old module whose names now live in several modules: each name from its new home."""

    def __init__(self, name: str, homes: list[types.ModuleType]) -> None:
        super().__init__(name)
        self._homes = homes

    def __getattr__(self, attr: str) -> object:
        for home in self._homes:
            if attr in vars(home):
                return vars(home)[attr]
        raise AttributeError(f"module {self.__name__!r} has no attribute {attr!r}")

    def __dir__(self) -> list[str]:
        return sorted({n for home in self._homes for n in vars(home)})


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds the old paths of :data:`MOVED` and loads them as their new modules, with a warning."""

    def __init__(self) -> None:
        self._own_specs: dict[str, importlib.machinery.ModuleSpec] = {}

    def find_spec(self, fullname: str, path: object, target: object = None) -> importlib.machinery.ModuleSpec | None:
        old = fullname.removeprefix(__name__ + ".")
        if old == fullname or old not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        new = [f"{__name__}.{m}" for m in MOVED[spec.name.removeprefix(__name__ + ".")]]
        warnings.warn(
            f"{spec.name} moved to {' and '.join(new)}; import it from there (the old path goes in the next release)",
            DeprecationWarning,
            stacklevel=2,
        )
        homes = [importlib.import_module(m) for m in new]
        if len(homes) > 1:
            return _SplitModule(spec.name, homes)
        self._own_specs[spec.name] = homes[0].__spec__
        return homes[0]

    def exec_module(self, module: types.ModuleType) -> None:
        """Nothing to run; a moved module gets back its own spec, which the import machinery replaced."""
        own = self._own_specs.pop(module.__spec__.name, None)
        if own is not None:
            module.__spec__ = own


sys.meta_path.insert(0, _MovedFinder())
