"""Jobs (long work with progress) and sweeps (one analysis over a family of linkages)."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from service.schemas.common import (
    EXAMPLE_LINKAGE,
    Finite,
    Ident,
    Linkage,
    Strict,
    Tolerances,
    examples,
)
from service.schemas.critical_values import CellSigns
from service.schemas.space import SpaceOptions

#: Points of one sweep (grid cells or samples): a bound on its cost and on its answer's size.
MAX_SWEEP_POINTS = 100_000

JobStatusName = Literal["queued", "running", "done", "failed", "cancelled"]
Compute = Literal["components", "critical", "margin", "windings"]
_PositiveFinite = Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)]


class JobRequest(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"operation": "analysis/critical-points", "body": {"linkage": EXAMPLE_LINKAGE}}))

    operation: str = Field(
        min_length=1, max_length=100,
        description="an analysis path, e.g. analysis/configuration-space (see /v1/jobs/operations)",
    )
    body: dict[str, Any] = Field(description="the request body that path takes")


class Progress(BaseModel):
    fraction: float = Field(ge=0, le=1, description="0..1, reported by the engine as it works")
    message: str


class JobError(BaseModel):
    title: str
    detail: str
    loc: list[str | int] = Field(default_factory=list)


class JobSummary(BaseModel):
    """A job without its result (``GET /v1/jobs``); times are RFC 3339, UTC."""

    id: str
    operation: str
    status: JobStatusName
    progress: Progress
    created: datetime = Field(description="when it was submitted (RFC 3339, UTC)")
    started: datetime | None = Field(description="when a worker first reported on it")
    finished: datetime | None = Field(description="when it ended: done, failed or cancelled")
    expires: datetime | None = Field(
        description="when a finished job and its result are forgotten (LINKAGE_JOB_TTL_S)"
    )
    error: JobError | None = None
    partial: bool = Field(
        False, description="the result holds only the work finished before the job stopped "
        "(time limit, cancel, a lost worker): a sweep's finished rows, an analysis's "
        "incomplete answer")


class JobOut(JobSummary):
    result: Any | None = Field(
        None, description="when done: the JSON the synchronous endpoint answers (for sweeps: "
        "rows and summary; for figures: the SVG as a string, another format as a data: URL, "
        "base64); when failed or cancelled: what "
        "was finished, if anything (partial)"
    )


class OperationOut(BaseModel):
    operation: str
    request: str = Field(description="name of the request schema of its body")


class PresetRef(Strict):
    name: Ident
    parameters: dict[Ident, Finite] = Field(default_factory=dict, max_length=100)


class GridAxisIn(Strict):
    min: Finite
    max: Finite
    steps: Annotated[int, Field(strict=True, ge=1, le=MAX_SWEEP_POINTS)]


class SampleAxisIn(Strict):
    mean: Finite
    sd: Annotated[float, Field(strict=True, ge=0, allow_inf_nan=False)]


class SweepRequest(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"preset": {"name": "four-bar"}, "grid": {"L2": {"min": 0.5, "max": 2.0, "steps": 4}},
         "seed": 0, "compute": ["components", "critical"]}))

    linkage: Linkage | None = Field(
        None, description="a linkage whose bars (the grid's or samples' keys) change length"
    )
    preset: PresetRef | None = Field(
        None, description="instead of a linkage: a preset whose parameters change"
    )
    grid: dict[Ident, GridAxisIn] | None = Field(None, min_length=1, max_length=8)
    samples: dict[Ident, SampleAxisIn] | None = Field(None, min_length=1, max_length=100)
    count: Annotated[int, Field(strict=True, ge=1, le=MAX_SWEEP_POINTS)] | None = Field(
        None, description="Monte Carlo points (with samples)"
    )
    seed: Annotated[int, Field(strict=True, ge=0, le=2**32 - 1)] = 0
    compute: list[Compute] = Field(default_factory=lambda: list[Compute](["components"]),
                                   min_length=1, max_length=4)
    tolerances: Tolerances | None = None
    options: SpaceOptions | None = None

    @model_validator(mode="after")
    def _one_of_each(self) -> SweepRequest:
        if (self.linkage is None) == (self.preset is None):
            raise ValueError("give exactly one of linkage and preset")
        if (self.grid is None) == (self.samples is None):
            raise ValueError("give exactly one of grid and samples")
        if self.samples is not None and self.count is None:
            raise ValueError("samples need a count")
        if self.grid is not None:
            if self.count is not None:
                raise ValueError("count goes with samples, not with a grid")
            cells = 1
            for axis in self.grid.values():
                cells *= axis.steps
                if not axis.min <= axis.max:
                    raise ValueError("every grid axis needs min <= max")
            if cells > MAX_SWEEP_POINTS:
                raise ValueError(f"the grid has {cells} points, more than {MAX_SWEEP_POINTS}")
        return self


class SweepRow(BaseModel):
    lengths: dict[str, float] = Field(description="the swept values of this point")
    components: int | str | None = Field(
        None, description="components of the configuration space; beyond 2^53 - 1 (the "
        "largest integer a JSON number holds exactly) a decimal string")
    complete: bool | None = Field(
        None, description="false: the count is a lower bound (a search budget cut it short, or "
        "no argument proves it)")
    argument: Literal["derived", "proved"] | None = Field(
        None, description="what proves the count exact (as search.argument): derived (a "
        "closed form, the chain rules) or proved")
    critical_points: int | None = None
    margin: float | None = None
    windings: list[str] | None = Field(None, description="distinct rotor-turn patterns")
    gated: bool | None = Field(
        None, description="no rotor completes a turn on any component: from the chain rules "
        "where they apply (the gate four-bar's Grashof type and the chain's cells), false where "
        "a traced component turns a rotor, true only where every component was traced; else "
        "null (see gated_reason)")
    gated_reason: str | None = Field(
        None, description="why gated is what it is (the rule, the traced rotors that turn), or "
        "why it is null")
    tau_signs: list[CellSigns] | None = Field(
        None, description="the tau signs at the point's lengths of every four-bar cell whose "
        "sides a swept name sets (a bar of the cell or the gate's D; a preset parameter that is "
        "not a bar, such as a or r, sets every cell), the gate four-bar first, as a map's "
        "regions carry them; null: no such cell (not a rotor chain, with or without the "
        "paper's gate) or no linkage at the point")
    error: str | None = None


class SweepSummary(BaseModel):
    points: int
    topologies: dict[str, int] = Field(description="rows per topology label")
    gated: int | None
    fraction_gated: float | None
    smallest_margin: float | None
    smallest_margin_at: dict[str, float] | None
    critical: int | None = Field(description="rows at critical lengths (a critical point)")
    incomplete: int
    errors: int


class SweepResult(BaseModel):
    partial: bool = Field(
        False, description="the rows of the points finished before the sweep stopped (time "
        "limit, cancel, a failed task); the other points have no row")
    rows: list[SweepRow]
    summary: SweepSummary
