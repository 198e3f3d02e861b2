"""One method registry serves both evaluation protocols (plugins/segmenter/evaluation/_methods.py,
docs/segmentation.md): no other segmenter module compares a string with a method's name."""

import re
from pathlib import Path

import handflow.plugins.segmenter as segmenter
from handflow.plugins.segmenter.evaluation import DEFAULT_METHODS, METHODS, REGISTRY

SOURCES = Path(segmenter.__file__).parent
REGISTRY_MODULE = SOURCES / "evaluation" / "_methods.py"
COMPARISON = re.compile(r"==|!=|\bin\b|\bmatch\b|\bcase\b")


def test_the_registry_names_every_method_of_both_protocols():
    assert set(METHODS) <= set(REGISTRY) and set(DEFAULT_METHODS) <= set(REGISTRY)
    assert METHODS == ("ukr_only", "ukr_clm", "dtw_1nn", "hmm")
    assert all(name == method.name for name, method in REGISTRY.items())


def test_no_module_outside_the_registry_compares_a_string_with_a_method_name():
    names = "|".join(re.escape(n) for n in REGISTRY)
    quoted = re.compile(rf"""["']({names})["']""")
    found = [
        f"{path.relative_to(SOURCES)}:{k}: {line.strip()}"
        for path in sorted(SOURCES.rglob("*.py"))
        if path != REGISTRY_MODULE
        for k, line in enumerate(path.read_text().splitlines(), 1)
        if quoted.search(line) and COMPARISON.search(line)
    ]
    assert not found, "choose by the registry's attributes instead:\n" + "\n".join(found)


def test_the_check_finds_a_comparison():
    assert COMPARISON.search('if method == "ukr_clm":') and re.search(
        r"""["'](ukr_clm)["']""", 'if method == "ukr_clm":'
    )
