"""Files shipped inside the installed package, found with :mod:`importlib.resources`.

Graphs, training configs, glove profiles, calibrations and models live in ``handflow.configs``
(the repository's ``configs/``); the recordings they were trained from in ``handflow.recordings``
(docs/architecture.md).  Commands read these as defaults and never write into them.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path


def shipped(*parts: str) -> Path:
    """Path of a shipped file or folder below ``configs/`` (it may not exist)."""
    return Path(str(resources.files("handflow.configs").joinpath(*parts)))


def shipped_recording(name: str) -> Path:
    """Path of a shipped recording below ``recordings/`` (it may not exist)."""
    return Path(str(resources.files("handflow.recordings").joinpath(name)))
