"""Choices are ``Literal`` types, so ``handflow validate`` names a typo with file:line."""

from pathlib import Path

import pytest

from handflow.framework.graphs.model import validate_file

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


@pytest.mark.parametrize(
    ("graph", "good", "typo"),
    [("cap_turning.yaml", "scene: cap", "scene: cpa"), ("cap_turning.yaml", "hand: shadow", "hand: shadwo")],
)
def test_a_typo_in_a_choice_of_a_shipped_graph_fails_validate_with_its_line(tmp_path, graph, good, typo):
    text = (CONFIGS / graph).read_text()
    line = 1 + text.splitlines().index(next(s for s in text.splitlines() if s.strip() == good))
    path = tmp_path / graph
    path.write_text(text.replace(good, typo, 1))
    assert validate_file(CONFIGS / graph)[1] == []
    _, problems = validate_file(path)
    field = typo.split(":")[0]
    assert any(p.line == line and f"param {field}" in p.message and "should be" in p.message for p in problems)
