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
        None, min_length=1, max_length=10_000,
        description="bars that may change (default: every bar with a free end)"
    )
    tolerances: Tolerances | None = None
    options: SpaceOptions | None = None
    method: Literal["auto", "closed-form", "multistart"] | None = Field(
        None, description="auto (default): the exact closed form for one-loop planar dyad chains "
        "(four-bars) and for spherical four-bars over one or two of their chords, else the "
        "multistart; closed-form: 422 where it does not apply; "
        "multistart: always the multistart", json_schema_extra=default_of("auto"),
    )


class RobustnessSearch(BaseModel):
    complete: bool = Field(description="the margin is exact: the closed form (argument "
                           "derived); a multistart is an upper bound and never complete")
    reason: Literal["time", "budget", "searched"] | None = Field(
        description="why the search is incomplete (time: the deadline stopped the starts; "
        "searched: every planned start ran, but a multistart finds an upper bound)"
    )
    argument: Literal["derived", "proved"] | None = Field(
        None, description="what proves the margin exact (derived: the closed form)")
    argument_detail: str | None = Field(None, description="the argument in a sentence")
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
    guarantee: Literal["exact", "upper-bound"] = Field(
        description="what the margin is: exact (closed form), or upper-bound (multistart: a "
        "critical value lies at this distance, found and checked; a nearer one may have been "
        "missed)"
    )
    guarantee_detail: str = Field(
        description="how the margin was found (the closed form's hyperplane, or the best local "
        "minimum over the converged starts)"
    )
    exact_margin: float | None = Field(
        description="multistart where the closed form applies too: the exact margin it was "
        "compared with (success is false where they differ); null otherwise"
    )
    search: RobustnessSearch
    tolerances: TolerancesUsed
