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
    homotopy_paths_max: Annotated[int, Field(strict=True, ge=0, le=8192)] | None = Field(
        None, description="largest path count of the homotopies that sweep the box's edges "
        "(the argument that every curve was found) and prove the regions' counts; 0 skips "
        "them: the curves are traced from the seed lengths only (search.reason then at best "
        "searched), a fast provisional map (default 512)", json_schema_extra=default_of(512),
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


class CellSigns(BaseModel):
    """The tau signs of one four-bar cell (the paper's Eq. 16, after McCarthy)."""

    cell: str = Field(description="``gate`` (the gate four-bar of a gated chain, the cell the "
                      "paper's Fig. 5b labels) or the chain's cell ``r0-l0-r1``")
    bars: list[str] = Field(description="the cell's input rotor, coupler and output rotor")
    sides: list[float] = Field(description="(a, L1, L2, L3): ground, input, coupler, output")
    signs: list[Literal[-1, 0, 1]] = Field(
        description="signs of tau_1 = a - L1 + L2 - L3, tau_2 = a - L1 - L2 + L3, "
        "tau_3 = L2 + L3 - a - L1 (0: critical lengths); the input rotor turns fully iff "
        "(+,+,+) or (-,-,+)")


class RegionOut(BaseModel):
    point: list[float]
    components: int | str | None = Field(
        description="components of the configuration space at the point: exact where "
        "``components_exact``, else the number traced (a lower bound); beyond 2^53 - 1 (a "
        "chain the rules count) a decimal string; null: not explored within the time budget "
        "(search.complete is then false)"
    )
    signature: str
    cells: int = Field(description="raster cells of the region")
    argument: Literal["derived", "proved"] | None = Field(
        None, description="what proves ``components`` exact (the exploration's "
        "search.argument, or derived from the chain rules); null: a lower bound, or not "
        "explored")
    components_exact: bool | None = Field(
        default=None, description="``components`` is the exact count (false: a lower bound, the "
        "components traced); null: not explored")
    components_traced: int | None = Field(
        default=None, description="components traced at the point (fewer than ``components`` where "
        "the chain rules count more than the search's budget traced)")
    components_rule: str | None = Field(
        default=None, description="the rule that counts the components exactly (rotor chains, "
        "chains with the paper's gate); null: no rule applies")
    tau_signs: list[CellSigns] | None = Field(
        default=None, description="the tau signs of every four-bar cell that one of the axes is "
        "a side of (the gate four-bar first; the other cells' signs are the same in every "
        "region); null: no such cell (or not explored)")
    gated: bool | None = Field(
        default=None, description="chains with the paper's gate: no rotor completes a turn on any "
        "component, decided from the gate four-bar and the chain's cells (not from what was "
        "traced); null: no gate, or undecided (``gated_reason`` says why)")
    gated_reason: str | None = Field(default=None, description="why ``gated`` is what it is")
    windings: list[str] | None = Field(
        default=None, description="the distinct patterns of the rotors' full turns on the traced "
        "components, e.g. ``r0:1,r1:1,D:0``")


class SliceSearch(SearchReport):
    """The search of a slice: complete when its curves are every critical curve in the box (the
    closed form of a one-dyad chain, derived; or traced from complete sweeps and from every
    turning point of a curve in the box, proved: ``turning_paths``, ``turning_points``,
    ``turning_points_traced``, ``turning_complete``) and every region's count is exact
    (``argument``); otherwise ``reason`` is time (the deadline stopped it) or searched (traced
    curves without that proof, or a region whose count is a lower bound)."""

    regions_explored: int = Field(description="regions whose components were counted")
    curves: int = Field(description="curves of the critical value set traced")
    resolution: int


class CriticalValuesResponse(BaseModel):
    curves: list[list[list[float]]] = Field(description="polylines [[x, y], ...] in the box")
    regions: list[RegionOut]
    search: SliceSearch
    tolerances: TolerancesUsed
