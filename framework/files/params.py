"""The one strict base of every parameter and configuration model (docs/pipelines.md, "Parameters").

Node ``Params``, graph settings, training configs, glove profiles and calibrations all derive
from :class:`StrictModel`: an unknown key is an error, so a typo is reported with its file and line
instead of being ignored. Choices are ``Literal`` types, so ``handflow validate`` lists the
allowed values.  Parameters a running node can take are marked with :func:`live` (docs/tuning.md).
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field
from pydantic_core import PydanticUndefined


class StrictModel(BaseModel):
    """A pydantic model that rejects unknown keys."""

    model_config = ConfigDict(extra="forbid")


LIVE = "live"
"""Key of the JSON-schema extra that marks a parameter a running node can take (docs/tuning.md)."""


def live(default: Any = PydanticUndefined, **field: Any) -> Any:
    """A ``Field`` a running node can take without a restart (``handflow param set``, docs/tuning.md).

    Use it like ``Field``: ``gain: float = live(1.0, description="...")``; the node gets a new value
    through :meth:`handflow.framework.plugin.Node.on_params`, validated by the same model as at start.
    """
    extra = dict(field.pop("json_schema_extra", None) or {})
    return Field(default, json_schema_extra={**extra, LIVE: True}, **field)


def live_keys(model: type[BaseModel]) -> frozenset[str]:
    """The parameters of ``model`` marked :func:`live`."""
    return frozenset(
        name
        for name, info in model.model_fields.items()
        if isinstance(info.json_schema_extra, dict) and info.json_schema_extra.get(LIVE)
    )
