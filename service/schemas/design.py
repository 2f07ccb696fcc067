"""Requests and responses of ``/v1/design/splitting`` (``service.routers.design``)."""

from __future__ import annotations

from typing import Annotated

from pydantic import AfterValidator, BaseModel, ConfigDict, Field
from pydantic_core import PydanticCustomError

from service.schemas.common import (
    EXAMPLE_LINKAGE,
    EXAMPLE_TOLERANCES,
    Linkage,
    SearchReport,
    Strict,
    Tolerances,
    TolerancesUsed,
    UniqueIdents,
    examples,
)
from service.schemas.space import SpaceOptions


def _nonzero(sign: int) -> int:
    if sign == 0:
        raise PydanticCustomError("sign", "sign must be 1 or -1")
    return sign


class TargetIn(Strict):
    branch_point: Annotated[int, Field(strict=True, ge=0)]
    sign: Annotated[int, Field(strict=True, ge=-1, le=1, json_schema_extra={"enum": [-1, 1]}),
                    AfterValidator(_nonzero)]


class DesignRequest(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"linkage": EXAMPLE_LINKAGE, "targets": [{"branch_point": 0, "sign": 1}],
         "adjustable": ["L2", "L3"], "max_change": 0.2, "margin": 1e-4,
         "tolerances": EXAMPLE_TOLERANCES}))

    linkage: Linkage
    targets: list[TargetIn] = Field(min_length=1, max_length=1000)
    adjustable: UniqueIdents = Field(min_length=1, max_length=10_000,
                                     json_schema_extra={"uniqueItems": True})
    max_change: Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)] | None = None
    margin: Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)] | None = Field(
        None, description="required sign * Delta / |dDelta/dL| (default 1e-4 of the median "
        "bar length)"
    )
    tolerances: Tolerances | None = None
    options: SpaceOptions | None = None


class PredictedOut(BaseModel):
    branch_point: int
    sign: int = Field(description="sign of delta where |delta| > delta_error, else 0 "
                      "(undecided: the target is not verified)")
    delta: float
    delta_error: float = Field(description="the scale of delta's own error (as in splitting)")
    connects: list[list[int]] = Field(description="joined ray pairs (empty where sign is 0)")
    traced_connects: list[list[int]] | None = Field(
        description="ray pairs found by tracing the perturbed linkage"
    )


class ConflictOut(BaseModel):
    branch_points: list[int]
    reason: str


class DesignResponse(BaseModel):
    feasible: bool
    perturbation: dict[str, float]
    largest_change: float
    predicted: list[PredictedOut]
    conflicts: list[ConflictOut]
    verified: bool | None = Field(
        description="the perturbed linkage, re-traced, agrees (null: infeasible, or not every "
        "target re-traced within the time budget)"
    )
    search: SearchReport = Field(
        description="the critical-point search behind the answer (as in critical-points): "
        "complete, reason, time_budget_s"
    )
    tolerances: TolerancesUsed
