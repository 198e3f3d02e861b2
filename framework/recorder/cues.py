"""Cued collection: the order of the cues and the cue messages (``handflow collect``, docs/recording.md, "Cued collection").

A *round* is one repetition of every class; within a round the order is shuffled with the seed and
the round's number (``numpy.random.default_rng([seed, round])``), so ``--append`` continues a
session with the rounds it would have had.  Each repetition is a cue of ``cue_s`` seconds
followed by ``rest_s`` seconds of rest; the cue topic carries one :class:`Label` per change:
the class (``index`` = repetition number in the session), :data:`REST`, and ``""`` at the end.
An interrupted repetition is withdrawn with ``""`` at its own stamp (:mod:`..files.labels`).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..files.labels import topic_intervals
from ..files.mcap_reader import iter_recording
from ..messages import Label

REST = "rest"
"""The label of the rest periods: a class no model is trained for (docs/segmentation.md)."""
RESERVED = (REST, "unknown", "")


@dataclass(frozen=True)
class Cue:
    """Repetition ``index`` (0-based in the session) of ``label`` in round ``round``."""

    round: int
    index: int
    label: str


def check_classes(classes: Sequence[str]) -> list[str]:
    """The class names, or ValueError: unique, non-empty, none of :data:`RESERVED`, no comma or ``_``."""
    names = [c.strip() for c in classes]
    bad = [c for c in names if c in RESERVED or "," in c or "_" in c or not c.isprintable()]
    if bad or not names:
        raise ValueError(
            f"--classes needs one or more names without '_' or ','; {bad or 'none'} cannot be used "
            f"({', '.join(repr(r) for r in RESERVED)} are reserved)"
        )
    if len(set(names)) != len(names):
        raise ValueError(f"--classes names a class twice: {names}")
    return names


def schedule(classes: Sequence[str], rounds: int, seed: int = 0, first_round: int = 0) -> Iterator[Cue]:
    """The cues of rounds ``first_round … first_round + rounds − 1``, each round shuffled (module docstring)."""
    for r in range(first_round, first_round + rounds):
        order = np.random.default_rng([seed, r]).permutation(len(classes))
        for k, c in enumerate(order):
            yield Cue(r, r * len(classes) + k, classes[int(c)])


def cue_message(label: str, index: int, classes: Sequence[str], stamp_ns: int) -> Label:
    """The cue topic's message: ``label`` from ``stamp_ns`` on."""
    msg = Label(label=label, index=index, classes=list(classes))
    msg.header.stamp_ns = stamp_ns
    return msg


def recorded_cues(path: str | Path, topic: str) -> tuple[list[str], int, int]:
    """The classes, the number of finished repetitions and the next round's number of a session's cue
    ``topic`` (``--append``); no classes when the topic holds no cue."""
    marks, classes, end, last_round = [], [], 0, -1
    for rm in iter_recording(path, [topic]):
        msg = rm.decode()
        marks.append((msg.header.stamp_ns, msg.label))
        classes = classes or list(msg.classes)
        end = max(end, msg.header.stamp_ns)
        if msg.label not in RESERVED and msg.classes:
            last_round = max(last_round, msg.index // len(msg.classes))
    finished = sum(i.label not in RESERVED for i in topic_intervals(marks, end))
    return classes, finished, last_round + 1
