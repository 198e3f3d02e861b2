"""The one strict base of every parameter and configuration model (docs/pipelines.md, "Parameters").

Node ``Params``, graph settings, training configs, glove profiles and calibrations all derive
from :class:`StrictModel`: an unknown key is an error, so a typo is reported with its file and line
instead of being ignored. Choices are ``Literal`` types, so ``handflow validate`` lists the
allowed values.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class StrictModel(BaseModel):
    """A pydantic model that rejects unknown keys."""

    model_config = ConfigDict(extra="forbid")
