"""Requests and responses of the configuration-space family of endpoints."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, Field

from service.schemas.analysis import Projection
from service.schemas.common import (
    BarValues,
    Finite,
    Ident,
    Linkage,
    Strict,
    Tolerances,
    TolerancesUsed,
    VertexVectors,
)

_StrainTol = Annotated[float, Field(strict=True, gt=0, le=0.2, allow_inf_nan=False)]


TimeBudget = Annotated[float, Field(strict=True, gt=0, le=86_400, allow_inf_nan=False)]
TIME_BUDGET_DOC = (
    "seconds the search may take before it answers with what it found, marked "
    "search.complete = false with search.reason = \"time\" (default LINKAGE_SEARCH_TIME_S, 4 s; "
    "at most three quarters of LINKAGE_TIME_LIMIT_S: a larger value is lowered to that, and "
    "search.time_budget_s says what was used). Jobs use the job's time limit instead."
)


class SpaceOptions(Strict):
    max_points: Annotated[int, Field(strict=True, ge=10, le=200_000)] | None = Field(
        None, description="budget of points per traced curve (default 20000)"
    )
    strain_tol: _StrainTol | None = Field(
        None, description="largest relative bar strain of a predictor step (default 0.01)"
    )
    step_max: Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)] | None = Field(
        None, description="largest distance between consecutive points (default: a tenth of "
        "the median bar length)"
    )
    angles: Annotated[int, Field(strict=True, ge=4, le=2000)] | None = Field(
        None, description="rotor angles swept for seeds (default 60)"
    )
    random_starts: Annotated[int, Field(strict=True, ge=0, le=1000)] | None = Field(
        None, description="random starts for seeds and for the critical-point search (default 12)"
    )
    max_components: Annotated[int, Field(strict=True, ge=1, le=1000)] | None = Field(
        None, description="budget of traced components (default 32)"
    )
    seed: Annotated[int, Field(strict=True, ge=0, le=2**32 - 1)] | None = Field(
        None, description="seed of the random starts (default 0)"
    )
    time_budget_s: TimeBudget | None = Field(None, description=TIME_BUDGET_DOC)


class SpaceRequest(Strict):
    linkage: Linkage
    tolerances: Tolerances | None = None
    options: SpaceOptions | None = None


class CriticalPointOut(BaseModel):
    index: int
    configuration: VertexVectors
    kind: str = Field(description="branch, rigid or degenerate")
    reason: str | None
    self_stress: BarValues | None
    zero_modes: list[VertexVectors]
    q_eigenvalues: list[float] | None
    tangents: list[VertexVectors] = Field(description="rays +t0, -t0, +t1, -t1 are numbered 0..3")
    residual: float = Field(description="largest |l - L| at the critical configuration")
    stress_residual: float = Field(description="|J^T sigma| / |J|")


class NearMissOut(BaseModel):
    configuration: VertexVectors = Field(description="closest approach on the configuration space")
    singular_gap: float = Field(description="s_min / s_max of J there")
    distance: float = Field(description="configuration distance to the nearest critical "
                            "configuration (of nearby lengths)")
    length_gap: float = Field(description="largest length change that makes it critical")
    critical_configuration: VertexVectors


class CriticalPointsResponse(Projection):
    critical_points: list[CriticalPointOut]
    near_misses: list[NearMissOut]
    degenerate: bool = Field(description="a critical point is degenerate (e.g. non-isolated)")
    search: dict[str, object]
    tolerances: TolerancesUsed


class ComponentOut(BaseModel):
    closed: bool
    through_start: bool
    positions: dict[str, list[list[float]]] = Field(
        description="per vertex, the walk along the component (closed ones repeat the first "
        "point at the end)"
    )
    angles: dict[str, list[float]] = Field(description="unwrapped rotor angles along the walk")
    winding: dict[str, int | None] = Field(description="net turns of each rotor (closed only)")
    critical_points: list[int]


class SegmentOut(BaseModel):
    from_: int = Field(alias="from", serialization_alias="from")
    to: int
    component: int
    from_ray: int
    to_ray: int

    model_config = {"populate_by_name": True}


class SpaceResponse(Projection):
    components: list[ComponentOut]
    critical_points: list[CriticalPointOut]
    segments: list[SegmentOut] = Field(
        description="at critical lengths: which critical points each branch joins"
    )
    degenerate: bool
    search: dict[str, object]
    tolerances: TolerancesUsed


class SplittingRequest(Strict):
    linkage: Linkage
    perturbation: dict[Ident, Finite] = Field(description="{bar_id: dL}")
    tolerances: Tolerances | None = None
    options: SpaceOptions | None = None


class BranchSplitOut(BaseModel):
    index: int
    configuration: VertexVectors
    delta: float = Field(description="Delta of the conic (c - dc)^T Q (c - dc) = Delta")
    delta_linear: float = Field(description="first-order Delta = 4 sum sigma_a L_a dL_a")
    shift: list[float] = Field(description="dc, the centre shift on the zero modes")
    sign: int
    connects: list[list[int]] = Field(description="joined ray pairs")


class SplittingResponse(BaseModel):
    branch_points: list[BranchSplitOut]
    critical_points_found: int
    search: dict[str, object] = Field(
        description="the critical-point search behind the answer (as in critical-points): "
        "complete, reason, time_budget_s"
    )
    tolerances: TolerancesUsed


class TargetIn(Strict):
    branch_point: Annotated[int, Field(strict=True, ge=0)]
    sign: Annotated[int, Field(strict=True, ge=-1, le=1)]


class DesignRequest(Strict):
    linkage: Linkage
    targets: list[TargetIn] = Field(min_length=1, max_length=1000)
    adjustable: list[Ident] = Field(min_length=1, max_length=10_000)
    max_change: Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)] | None = None
    margin: Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)] | None = Field(
        None, description="required sign * Delta / |dDelta/dL| (default 1e-4 of the median "
        "bar length)"
    )
    tolerances: Tolerances | None = None
    options: SpaceOptions | None = None


class PredictedOut(BaseModel):
    branch_point: int
    sign: int
    delta: float
    connects: list[list[int]]
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
    search: dict[str, object] = Field(
        description="the critical-point search behind the answer (as in critical-points): "
        "complete, reason, time_budget_s"
    )
    tolerances: TolerancesUsed


class RobustnessRequest(Strict):
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
        "multistart: always the multistart"
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


class AxisIn(Strict):
    bar: Ident
    min: Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)]
    max: Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)]


class CriticalValuesOptions(Strict):
    resolution: Annotated[int, Field(strict=True, ge=8, le=400)] | None = Field(
        None, description="raster of the regions and step of the curves: box / resolution "
        "(default 48)"
    )
    seeds_per_axis: Annotated[int, Field(strict=True, ge=2, le=20)] | None = Field(
        None, description="sample lengths per axis where curves are seeded (default 5)"
    )
    time_budget_s: TimeBudget | None = Field(None, description=TIME_BUDGET_DOC)


class CriticalValuesRequest(Strict):
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


class CriticalValuesResponse(BaseModel):
    curves: list[list[list[float]]] = Field(description="polylines [[x, y], ...] in the box")
    regions: list[RegionOut]
    search: dict[str, object]
    tolerances: TolerancesUsed
