"""The base of every case-file model: strict (unknown keys refused), finite numbers only."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]


class StrictModel(BaseModel):
    """The base of every case-file model: unknown fields refused, assignments validated, NaN
    and inf refused (the two-body case format, dem.rocking.schema, builds on it too)."""

    # NaN and inf are refused in every number ("Input should be a finite number"), before any
    # range check could give a misleading message about them
    model_config = ConfigDict(extra="forbid", validate_assignment=True, allow_inf_nan=False)

