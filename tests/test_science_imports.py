"""The science of every family imports no Zenoh and nothing of the runtime (docs/architecture.md).

Each family's modules are imported one by one in a fresh interpreter (one per family); after each
import, no ``zenoh*`` module and no runtime part of the framework may be loaded.  Node wrappers and
command-line modules are the families' runtime side and are left out (listed below).  The
import-linter contracts in pyproject.toml say the same statically.
"""

from __future__ import annotations

import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import pytest

FAMILIES = ("manifold", "segmenter", "grasp", "manipulation", "mapping", "hands", "tracker", "glove", "camera")
# the families' runtime side: node wrappers, command-line modules, and what drives nodes
NODE_AND_CLI_NAMES = {"nodes", "node", "cli"}
NODE_DRIVERS = {
    "handflow.plugins.manipulation.evaluation",  # runs the manipulation nodes in a NodeHarness
}
RUNTIME = tuple(
    f"handflow.framework.{part}"
    for part in (
        "graphs",
        "network",
        "runtime",
        "recorder",
        "observe",
        "security",
        "testkit",
        "commands",
        "cli",
        "plugin",
        "registry",
    )
)

_CHECK = """
import importlib, json, pkgutil, sys
family, runtime, skip_names, skip = sys.argv[1], tuple(sys.argv[2].split()), set(sys.argv[3].split()), set(sys.argv[4].split())
package = importlib.import_module(f"handflow.plugins.{family}")
found, checked = [], []
for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
    parts = info.name.split(".")
    if info.name in skip or any(p in skip_names for p in parts[3:]):
        continue
    importlib.import_module(info.name)
    checked.append(info.name)
    bad = sorted(m for m in sys.modules if m.split(".")[0] == "zenoh" or m.startswith("zenoh") or m.startswith(runtime))
    if bad:
        found.append((info.name, bad))
        break
print(json.dumps({"checked": checked, "found": found}))
"""


def _check(family: str) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", _CHECK, family, " ".join(RUNTIME), " ".join(NODE_AND_CLI_NAMES), " ".join(NODE_DRIVERS)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def results() -> dict[str, dict]:
    with ThreadPoolExecutor(2) as pool:
        return dict(zip(FAMILIES, pool.map(_check, FAMILIES)))


@pytest.mark.parametrize("family", FAMILIES)
def test_science_imports_no_runtime(family, results):
    result = results[family]
    assert result["checked"], f"no science module found in {family}"
    assert not result["found"], f"importing {result['found'][0][0]} loads {result['found'][0][1]}"
