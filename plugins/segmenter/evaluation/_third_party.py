"""Warnings of third-party libraries during an evaluation, counted per fold and summarised once
(docs/segmentation.md, "reading the output"): hmmlearn logs "Model is not converging" whenever
EM's log-likelihood dips by a rounding error, dozens of times per evaluation, and the figures use
the model it stopped at either way."""

from __future__ import annotations

import logging
import re
import warnings
from collections import Counter
from contextlib import contextmanager

LOGGERS = ("hmmlearn.base",)  # third-party loggers whose warnings are counted instead of printed


def _gist(message: str) -> str:
    """A message's first sentence without its numbers: one key for every repeat of it."""
    first = re.split(r"(?<=[.!?])\s", message.strip(), maxsplit=1)[0]
    return re.sub(r"[-+]?\d[\d.eE+-]*", "…", first)


class _Counting(logging.Filter):
    def __init__(self, counts: Counter) -> None:
        super().__init__()
        self.counts = counts

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno < logging.WARNING or record.levelno >= logging.ERROR:
            return True
        self.counts[f"{record.name}: {_gist(record.getMessage())}"] += 1
        return False


@contextmanager
def counted_warnings(counts: Counter):
    """Within the block, warnings (``warnings`` and the :data:`LOGGERS`' log records of level
    WARNING) are added to ``counts`` by their gist instead of being printed."""
    counting = _Counting(counts)
    loggers = [logging.getLogger(name) for name in LOGGERS]
    for logger in loggers:
        logger.addFilter(counting)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield
    finally:
        for logger in loggers:
            logger.removeFilter(counting)
    for w in caught:
        counts[f"{w.category.__name__}: {_gist(str(w.message))}"] += 1


def summary(counts: Counter) -> list[str]:
    """One line per kind of warning, most frequent first."""
    return [f"{n} × {gist}" for gist, n in counts.most_common()]
