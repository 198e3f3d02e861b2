"""What handflow records of itself in the files it writes and the keys it derives (model files,
evaluation checkpoints, ``handflow --version``)."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version


def installed_version() -> str:
    """The installed handflow distribution's version ("unknown" when run from a source tree that
    is not installed)."""
    try:
        return version("handflow")
    except PackageNotFoundError:
        return "unknown"
