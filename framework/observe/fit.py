"""Tables that fit a terminal: one line per row (docs/monitoring.md, "Terminal width").

When the columns at their natural width do not fit, their headers are abbreviated, then columns are
dropped, least important first, until the rest fits; a ``flexible`` column (a last value) takes
the width left and is cut with an ellipsis.  ``width=None`` keeps every column at full width.
"""

from __future__ import annotations

from dataclasses import dataclass

from rich import box
from rich.table import Table
from rich.text import Text

GAP = 3
"""Characters between two columns (" │ " in :data:`rich.box.SIMPLE_HEAD` without edges)."""
MIN_FLEXIBLE = 20
"""A flexible column gets at least this width, or the columns behind it in priority are dropped."""


@dataclass(frozen=True)
class Column:
    header: str
    short: str  # the header when space is short
    cells: list[Text]
    priority: int  # 0 is kept longest
    justify: str = "left"
    flexible: bool = False


def _natural(col: Column, short: bool) -> int:
    header = col.short if short else col.header
    return max([len(header)] + [c.cell_len for c in col.cells])


def _width(columns: list[Column], short: bool) -> int:
    cells = sum(min(MIN_FLEXIBLE, _natural(c, short)) if c.flexible else _natural(c, short) for c in columns)
    return cells + GAP * (len(columns) - 1)


def _choose(columns: list[Column], width: int | None) -> tuple[list[Column], bool]:
    """The columns that fit ``width`` and whether their headers are the short ones."""
    if width is None or _width(columns, False) <= width:
        return columns, False
    chosen = list(columns)
    while len(chosen) > 1 and _width(chosen, True) > width:
        chosen.remove(max(chosen, key=lambda c: c.priority))
    return chosen, True


def fitted_table(title: str, columns: list[Column], width: int | None) -> Table:
    """A table of ``columns`` (display order), one line per row within ``width`` characters."""
    chosen, short = _choose(columns, width)
    table = Table(title=title, box=box.SIMPLE_HEAD, show_edge=False, pad_edge=False)
    fixed = sum(_natural(c, short) for c in chosen if not c.flexible) + GAP * (len(chosen) - 1)
    for col in chosen:
        flexible = col.flexible and width is not None
        table.add_column(
            col.short if short else col.header,
            justify=col.justify,
            no_wrap=True,
            overflow="ellipsis",
            max_width=max(MIN_FLEXIBLE, width - fixed) if flexible else None,
        )
    for row in zip(*(c.cells for c in chosen)):
        table.add_row(*row)
    return table
