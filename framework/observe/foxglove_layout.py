"""The flagship's Foxglove layout for any graph: ``handflow layout`` (docs/foxglove.md, "The flagship layout").

``configs/foxglove_layout.json`` names the topics of ``configs/demo.yaml``
(``/handflow/demo/<node>/<port>``).  :func:`layout_for` renames them for another graph, e.g.
``demo_segment_only``, which a demo recording is replayed into; :func:`unshown` names the layout's
topics that graph does not carry (their panels stay empty).
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

from ..files.resources import shipped

if TYPE_CHECKING:
    from ..graphs.model import Graph

FLAGSHIP = "demo"
"""The graph whose topics the shipped layout names."""
_TOPIC = re.compile(rf"/handflow/{FLAGSHIP}/(\w+/\w+)")


def flagship_layout() -> str:
    return shipped("foxglove_layout.json").read_text()


def layout_for(graph: str) -> str:
    """The shipped layout (JSON text) with its topics under ``/handflow/<graph>/``."""
    return flagship_layout().replace(f"/handflow/{FLAGSHIP}/", f"/handflow/{graph}/")


def carried(graph: Graph) -> set[str]:
    """The ``node/port`` topics of ``graph``: its nodes' outputs and the topics fed from outside."""
    outputs = {f"{nid}/{port}" for nid, rn in graph.nodes.items() for port in rn.cls.output_types(rn.params)}
    return outputs | set(graph.spec.external)


def unshown(graph: Graph) -> list[str]:
    """The layout's topics (``node/port``) that ``graph`` does not carry."""
    return sorted(set(_TOPIC.findall(flagship_layout())) - carried(graph))
