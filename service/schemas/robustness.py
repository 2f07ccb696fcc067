"""Requests and responses of ``/v1/analysis/robustness``."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.common import (
    EXAMPLE_LINKAGE,
    EXAMPLE_TOLERANCES,
    Ident,
    Linkage,
    Strict,
    Tolerances,
    TolerancesUsed,
    VertexVectors,
    default_of,
    examples,
)
from service.schemas.space import SpaceOptions


class RobustnessRequest(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"linkage": EXAMPLE_LINKAGE, "adjustable": ["L1", "L2", "L3"],
         "tolerances": EXAMPLE_TOLERANCES, "method": "auto"}))

    linkage: Linkage
    adjustable: list[Ident] | None = Field(
        None, max_length=10_000, description="bars that may change (default: every bar with a "
        "free end)"
    )
    tolerances: Tolerances | None = None
    options: SpaceOptions | None = None
    method: Literal["auto", "closed-form", "multistart"] | None = Field(
        None, description="auto (default): the exact closed form for one-loop planar dyad chains "
        "(four-bars), else the multistart; closed-form: 422 where it does not apply; "
        "multistart: always the multistart", json_schema_extra=default_of("auto"),
    )


class RobustnessSearch(BaseModel):
    complete: bool = Field(description="every planned start ran (always true for the closed "
                           "form)")
    reason: Literal["time", "budget"] | None = Field(
        description="why the search is incomplete (time: the deadline stopped the starts)"
    )
    starts_planned: int | None = Field(None, description="multistart: starts planned")
    starts_run: int | None = Field(None, description="multistart: starts run")
    critical_points_complete: bool | None = Field(
        None, description="multistart: the critical-point search that seeds it was complete"
    )
    planes: int | None = Field(None, description="closed form: critical hyperplanes tried")
    time_budget_s: float | None = Field(
        None, description="seconds the search was given (synchronous requests)"
    )


class RobustnessResponse(BaseModel):
    margin: float | None = Field(
        description="smallest Euclidean change of the adjustable lengths that reaches a critical "
        "value (null when none was found)"
    )
    nearest: dict[str, float] = Field(description="the nearest critical lengths")
    critical_configuration: VertexVectors
    starts: int = Field(description="local searches started")
    converged: int = Field(description="local searches that reached a critical configuration")
    success: bool
    message: str
    method: Literal["closed-form", "multistart"] = Field(description="the method that answered")
    guarantee: str = Field(
        description="what the margin is: exact (closed form), or the best local minimum over "
        "the converged starts (multistart)"
    )
    search: RobustnessSearch
    tolerances: TolerancesUsed
