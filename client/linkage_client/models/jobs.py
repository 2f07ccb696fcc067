"""Jobs, sweeps and the model of each job operation's result."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from linkage_client._build import Model, build
from linkage_client.models.analysis import (
    CellSigns,
    CriticalPointsResult,
    CriticalValuesResult,
    DesignResult,
    RigidityResult,
    RobustnessResult,
    SecondOrderResult,
    SpaceResult,
    SplittingResult,
)

JSON = dict[str, Any]


def _raw() -> Any:
    return field(default_factory=dict, repr=False, compare=False)


# ---------------------------------------------------------------- jobs and sweeps


@dataclass(frozen=True)
class Progress(Model):
    fraction: float
    message: str


@dataclass(frozen=True)
class JobError(Model):
    title: str
    detail: str
    loc: list[str | int] = field(default_factory=list)


#: Statuses after which a job no longer changes.
FINISHED = ("done", "failed", "cancelled")


@dataclass(frozen=True)
class JobSummary(Model):
    """A job without its result (``GET /v1/jobs``); times are RFC 3339 strings (UTC)."""

    id: str
    operation: str
    status: str
    progress: Progress
    created: str
    started: str | None = None
    finished: str | None = None
    expires: str | None = None
    error: JobError | None = None
    partial: bool = False


@dataclass(frozen=True)
class Job(JobSummary):
    """A job or sweep (``/v1/jobs/{id}``); ``result`` is the raw JSON when done (or, with
    ``partial``, what a stopped job finished)."""

    result: Any | None = None

    @property
    def location(self) -> str:
        return f"/v1/jobs/{self.id}"

    @property
    def done(self) -> bool:
        """True once the job can no longer change (done, failed or cancelled)."""
        return self.status in FINISHED


@dataclass(frozen=True)
class Operation(Model):
    operation: str
    request: str


@dataclass(frozen=True)
class SweepRow(Model):
    lengths: dict[str, float]
    components: int | None = None
    complete: bool | None = None
    critical_points: int | None = None
    margin: float | None = None
    windings: list[str] | None = None
    gated: bool | None = None
    gated_reason: str | None = None
    error: str | None = None
    tau_signs: list[CellSigns] | None = None


@dataclass(frozen=True)
class SweepSummary(Model):
    points: int
    topologies: dict[str, int]
    gated: int | None
    fraction_gated: float | None
    smallest_margin: float | None
    smallest_margin_at: dict[str, float] | None
    critical: int | None
    incomplete: int
    errors: int


@dataclass(frozen=True)
class SweepResult(Model):
    """A sweep's result: one row per grid cell or sample, and their summary."""

    rows: list[SweepRow]
    summary: SweepSummary
    raw: JSON = _raw()

    def column(self, name: str) -> np.ndarray:
        """One swept length (or ``components``, ``margin``, ...) of every row as an array
        (``nan`` where a row has none)."""
        values = [r.lengths.get(name) if name in r.lengths else getattr(r, name, None)
                  for r in self.rows]
        return np.array([np.nan if v is None else v for v in values], dtype=np.float64)


#: The model of each job operation's result (``None``: the raw JSON).
RESULTS: dict[str, type[Model]] = {
    "analysis/rigidity": RigidityResult,
    "analysis/second-order": SecondOrderResult,
    "analysis/critical-points": CriticalPointsResult,
    "analysis/configuration-space": SpaceResult,
    "analysis/splitting": SplittingResult,
    "analysis/robustness": RobustnessResult,
    "analysis/critical-values": CriticalValuesResult,
    "design/splitting": DesignResult,
    "sweeps": SweepResult,
}


def result_of(operation: str, data: Any) -> Any:
    """A job's result as the model of its operation (the raw JSON for an unknown one)."""
    model = RESULTS.get(operation)
    return build(model, data) if model is not None and isinstance(data, Mapping) else data
