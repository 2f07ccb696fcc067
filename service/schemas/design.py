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
from service.schemas.splitting import ConeSplitOut


def _nonzero(sign: int) -> int:
    if sign == 0:
        raise PydanticCustomError("sign", "sign must be 1 or -1")
    return sign


class TargetIn(Strict):
    branch_point: Annotated[int, Field(strict=True, ge=0, description=(
        "the critical point (one degree of freedom: as critical-points numbers them) or the "
        "cone (two degrees of freedom: as the splitting answer's surface.cones lists them)"))]
    sign: Annotated[int, Field(strict=True, ge=-1, le=1, json_schema_extra={"enum": [-1, 1]},
                               description="the sign of Delta asked for (required with one "
                               "degree of freedom; with two, give sign or sheets)"),
                    AfterValidator(_nonzero)] | None = None
    sheets: Annotated[int, Field(strict=True, ge=1, le=2, description=(
        "two degrees of freedom: resolve the cone into a hyperboloid of 1 sheet (its nappes "
        "joined by a neck) or 2 (parted)"))] | None = None


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


class SurfaceDesignOut(BaseModel):
    """Two degrees of freedom: how every cone resolves at L + dL, the predicted change of the
    topology and its check by meshing the linkage at L + dL and L - dL."""

    cones: list[ConeSplitOut] = Field(description="every cone found, at L + dL (targets "
                                      "number them)")
    asked: list[int] = Field(description="the sign of Delta each target asks for (sheets "
                             "turned into a sign by Q's eigenvalues)")
    targets_met: bool | None = Field(description="every target's cone resolves as asked "
                                     "(null: not re-meshed)")
    euler_change: int | None = Field(description="predicted chi(L + dL) - chi(L): sum of the "
                                     "cones' euler_change (null: a cone undecided)")
    predicted_euler_difference: int | None = Field(
        description="predicted chi(L + dL) - chi(L - dL) = 2 euler_change")
    euler: list[int | None] = Field(description="re-meshed Euler characteristics at L + dL "
                                    "and L - dL (summed over the surfaces)")
    betti_q: list[list[int] | None] = Field(description="re-meshed b0, b1, b2 over Q at "
                                            "L + dL and L - dL (summed over the surfaces)")
    remeshed_complete: bool = Field(description="both re-meshings complete (proved) and every "
                                    "path of the cone search ended")
    critical_betti_q: list[int] | None = Field(
        description="b0, b1, b2 over Q of the critical space at L, meshed through its "
        "cones (null: its mesh incomplete)")
    predicted_betti_q: list[list[int] | None] = Field(
        description="b0, b1, b2 over Q predicted at "
        "L + dL and L - dL: the critical space's mesh with each apex resolved as its cone "
        "resolves (two sheets: the apex split; one: a tube between its link's two cycles)")
    message: str


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
        description="the perturbed linkage, re-traced, agrees (two degrees of freedom: the "
        "targets are met and the complete re-meshings differ in Euler characteristic as "
        "predicted; null: infeasible, or not every target re-traced or re-meshed within the "
        "time budget)"
    )
    surface: SurfaceDesignOut | None = Field(
        None, description="two degrees of freedom (M - E = 2): the cones' resolution and the "
        "re-meshed topology; predicted is then empty")
    search: SearchReport = Field(
        description="the critical-point search behind the answer (as in critical-points): "
        "complete, reason, time_budget_s"
    )
    tolerances: TolerancesUsed
