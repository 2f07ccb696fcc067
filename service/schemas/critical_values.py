"""Requests and responses of ``/v1/analysis/critical-values`` (and its figure)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.common import (
    EXAMPLE_LINKAGE,
    EXAMPLE_TOLERANCES,
    Ident,
    Linkage,
    SearchReport,
    Strict,
    Tolerances,
    TolerancesUsed,
    default_of,
    examples,
)
from service.schemas.space import TIME_BUDGET_DOC, TimeBudget


class AxisIn(Strict):
    bar: Ident
    min: Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)]
    max: Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)]


class CriticalValuesOptions(Strict):
    resolution: Annotated[int, Field(strict=True, ge=8, le=400)] | None = Field(
        None, description="raster of the regions and step of the curves: box / resolution "
        "(default 48)", json_schema_extra=default_of(48),
    )
    seeds_per_axis: Annotated[int, Field(strict=True, ge=2, le=20)] | None = Field(
        None, description="sample lengths per axis where curves are seeded (default 5)",
        json_schema_extra=default_of(5),
    )
    time_budget_s: TimeBudget | None = Field(None, description=TIME_BUDGET_DOC)


class CriticalValuesRequest(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"linkage": EXAMPLE_LINKAGE, "axes": [{"bar": "L2", "min": 0.5, "max": 2.0},
                                    {"bar": "L3", "min": 0.5, "max": 2.0}],
         "options": {"resolution": 24, "seeds_per_axis": 5, "time_budget_s": 4.0},
         "tolerances": EXAMPLE_TOLERANCES}))

    linkage: Linkage
    axes: list[AxisIn] = Field(min_length=2, max_length=2)
    options: CriticalValuesOptions | None = None
    tolerances: Tolerances | None = None


class RegionOut(BaseModel):
    point: list[float]
    components: int | None = Field(
        description="components of the configuration space at the point (null: not explored "
        "within the time budget; search.complete is then false)"
    )
    signature: str
    cells: int = Field(description="raster cells of the region")
    argument: Literal["derived", "proved"] | None = Field(
        None, description="what proves ``components`` exact (the exploration's "
        "search.argument); null: a lower bound, or not explored")


class SliceSearch(SearchReport):
    """The search of a slice: complete when its curves are every critical curve in the box (the
    closed form of a one-dyad chain) and every region's count is exact (``argument``);
    otherwise ``reason`` is time (the deadline stopped it) or searched (traced curves, or a
    region whose count is a lower bound)."""

    regions_explored: int = Field(description="regions whose components were counted")
    curves: int = Field(description="curves of the critical value set traced")
    resolution: int


class CriticalValuesResponse(BaseModel):
    curves: list[list[list[float]]] = Field(description="polylines [[x, y], ...] in the box")
    regions: list[RegionOut]
    search: SliceSearch
    tolerances: TolerancesUsed
