"""Every import of handflow shown in README.md and docs/*.md uses today's module paths: it runs, in a
fresh interpreter, without a ``DeprecationWarning`` (old paths warn for one release; docs/architecture.md)."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PYTHON_BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def _imports(text: str) -> list[str]:
    """The ``import``/``from … import`` statements of handflow in the page's python blocks."""
    found = []
    for block in PYTHON_BLOCK.findall(text):
        try:
            tree = ast.parse(block)
        except SyntaxError:  # a fragment (e.g. a class body shown alone); its import lines are parsed one by one
            tree = ast.Module(body=[], type_ignores=[])
            for line in block.splitlines():
                try:
                    tree.body.extend(ast.parse(line.strip()).body)
                except SyntaxError:
                    continue
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("handflow"):
                found.append(ast.unparse(node))
            elif isinstance(node, ast.Import) and any(a.name.startswith("handflow") for a in node.names):
                found.append(ast.unparse(node))
    return found


def test_documented_imports_use_the_current_paths():
    pages = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
    statements = sorted({s for page in pages for s in _imports(page.read_text())})
    assert len(statements) >= 10, statements
    script = "\n".join(statements)
    res = subprocess.run(
        [sys.executable, "-W", "error::DeprecationWarning", "-c", script], capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 0, f"{res.stderr[-3000:]}\n--- the imports:\n{script}"
