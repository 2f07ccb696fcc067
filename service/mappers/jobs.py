"""Conversions of jobs and sweeps (sweep requests in; job states, sweep rows and CSV out)."""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

import numpy as np
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ValidationError

from engine.catalogue.presets import build_preset, parameter_bounds, resolve_parameters
from engine.design.region_labels import touched_cells
from engine.design.sweep import (
    COMPUTE,
    BarFamily,
    Family,
    GridAxis,
    PointResult,
    PresetFamily,
    SampleAxis,
    grid_points,
    sample_points,
    summarize,
)
from engine.model.errors import InvalidParameter, InvalidRequest, UnknownPreset
from engine.model.linkage import Limits
from engine.model.tolerances import Tolerances as EngineTolerances
from engine.model.tolerances import scaled_tolerances
from engine.space.configuration_space import (
    SpaceOptions,
)
from service.job_state import Job

#: Default margin of ``/v1/design/splitting``, relative to the median bar length.
from service.mappers.common import json_int, problem_in
from service.mappers.design import cell_signs_out
from service.mappers.space import space_options_in
from service.schemas import jobs as job_schemas


@dataclass(frozen=True)
class SweepJob:
    """A sweep request in engine terms: the family, its points (N, P) and what to compute;
    ``names`` are the swept bars or parameters (the columns of ``points``)."""

    family: Family
    points: np.ndarray
    compute: tuple[str, ...]
    tolerances: EngineTolerances
    options: SpaceOptions
    names: tuple[str, ...]
    cells: int = 0  # four-bar cells a row labels with tau signs (at the request's own linkage)


def sweep_in(body: job_schemas.SweepRequest, limits: Limits) -> SweepJob:
    """Validate a sweep (names, lengths, limits) before any point is analysed; an unknown
    bar or parameter is an error of the request, at ``grid``/``samples``."""
    axes_loc = "grid" if body.grid is not None else "samples"
    names = tuple(body.grid or body.samples or {})
    family: Family
    try:
        if body.linkage is not None:
            base, tol = problem_in(body.linkage, body.tolerances, limits)
            family = BarFamily(base, names)
        else:
            assert body.preset is not None
            base = build_preset(body.preset.name, body.preset.parameters, limits)
            given = body.tolerances.model_dump(exclude_none=True) if body.tolerances else {}
            tol = scaled_tolerances(float(np.median(base.lengths)), **given)
            family = PresetFamily(body.preset.name, dict(body.preset.parameters), names)
    except InvalidParameter as err:  # of the preset: in the body, not in a query
        raise InvalidRequest(err.message, loc=("preset", "parameters", *err.loc)) from None
    except UnknownPreset as err:  # in the body: a 422, not the 404 of a path
        raise InvalidRequest(err.message, loc=("preset", "name")) from None
    except InvalidRequest as err:
        if err.loc and isinstance(err.loc[0], int):  # k-th swept name
            raise InvalidRequest(err.message, loc=(axes_loc, names[err.loc[0]])) from None
        raise
    if body.grid is not None:
        _check_grid(body)
        points = grid_points([GridAxis(k, a.min, a.max, a.steps) for k, a in body.grid.items()])
    else:
        assert body.samples is not None and body.count is not None
        points = sample_points([SampleAxis(k, a.mean, a.sd) for k, a in body.samples.items()],
                               body.count, body.seed)
    compute = tuple(c for c in COMPUTE if c in body.compute)
    return SweepJob(family, points, compute, tol, space_options_in(body.options), names,
                    len(touched_cells(base, names)))


def _check_grid(body: job_schemas.SweepRequest) -> None:
    """Refuse (422 naming the axis) a grid with a point that no row could analyse whatever the
    other axes' values: a bar's length at most 0, a preset parameter outside its own bounds
    (an integer, a side, a positive length; ``gate`` below ``n`` joins two parameters, and
    Monte Carlo samples are random: those points are rows with an ``error``)."""
    assert body.grid is not None
    for name, axis in body.grid.items():
        values = np.linspace(axis.min, axis.max, axis.steps)
        if body.linkage is not None:
            if axis.min <= 0:
                raise InvalidRequest(f"a bar's length must be positive: min = {axis.min:g}",
                                     loc=("grid", name, "min"))
            continue
        assert body.preset is not None
        if parameter_bounds(body.preset.name)[name].below is not None:
            continue
        for value in values:
            try:
                resolve_parameters(body.preset.name, {**body.preset.parameters,
                                                      name: float(value)})
            except InvalidParameter as err:
                if err.loc == (name,):
                    raise InvalidRequest(f"the grid's point {name} = {value:g}: {err.message}",
                                         loc=("grid", name)) from None
                raise


def sweep_out(names: tuple[str, ...], rows: list[PointResult],
              partial: bool = False) -> job_schemas.SweepResult:
    s = summarize(rows)
    return job_schemas.SweepResult(
        partial=partial,
        rows=[
            job_schemas.SweepRow(
                lengths=dict(zip(names, r.values, strict=True)),
                components=None if r.components is None else json_int(r.components),
                complete=r.complete,
                argument=r.argument,
                critical_points=r.critical_points,
                margin=r.margin,
                windings=None if r.windings is None else list(r.windings),
                gated=r.gated,
                gated_reason=r.gated_reason,
                tau_signs=None if r.tau_signs is None else [cell_signs_out(c)
                                                            for c in r.tau_signs],
                error=r.error,
            )
            for r in rows
        ],
        summary=job_schemas.SweepSummary(
            points=s.points,
            topologies=s.topologies,
            gated=s.gated,
            fraction_gated=s.fraction_gated,
            smallest_margin=s.margin,
            smallest_margin_at=None if s.margin_at is None
            else dict(zip(names, s.margin_at, strict=True)),
            critical=s.critical,
            incomplete=s.incomplete,
            errors=s.errors,
        ),
    )


def job_body_in(model: type[BaseModel], body: dict[str, Any]) -> BaseModel:
    """A job's ``body`` validated as the synchronous endpoint validates its request (JSON
    mode); errors are located under ``body.body``."""
    try:
        return model.model_validate_json(json.dumps(body))
    except ValidationError as err:
        raise RequestValidationError(
            [{**e, "loc": ("body", "body", *e["loc"])} for e in err.errors()]
        ) from None


def _when(epoch: float | None) -> datetime | None:
    """A job's time (seconds since the epoch) as an aware UTC datetime (RFC 3339 in JSON)."""
    return None if epoch is None else datetime.fromtimestamp(epoch, UTC)


def job_summary_out(job: Job, expires: float | None) -> job_schemas.JobSummary:
    return job_schemas.JobSummary(
        id=job.id,
        operation=job.operation,
        status=job.status,  # type: ignore[arg-type]
        progress=job_schemas.Progress(fraction=job.fraction, message=job.message),
        created=datetime.fromtimestamp(job.created, UTC),
        started=_when(job.started),
        finished=_when(job.finished),
        expires=_when(expires),
        partial=job.partial,
        error=None if job.error is None else job_schemas.JobError(**job.error),
    )


def job_out(job: Job, expires: float | None) -> job_schemas.JobOut:
    """A job with its result (a large one kept as its worker's JSON, ``serialise.RawJSON``:
    the model is built without validation, so that the result is not walked)."""
    summary = job_summary_out(job, expires)
    return job_schemas.JobOut.model_construct(**dict(summary), result=job.result)


#: Columns of a sweep's CSV after the swept names, in this order.
SWEEP_CSV_COLUMNS = ("components", "complete", "argument", "critical_points", "margin", "gated",
                     "gated_reason", "windings", "tau_signs", "error")


def sweep_csv(result: dict[str, Any]) -> str:
    """A sweep's rows as CSV: one row per point, the swept values first (empty cells where a
    value was not computed; windings joined by ``|``; tau signs as ``cell:s1,s2,s3`` joined by
    ``|``, e.g. ``gate:1,1,-1``)."""
    rows = result["rows"]
    names = list(rows[0]["lengths"]) if rows else []
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([*names, *SWEEP_CSV_COLUMNS])
    for row in rows:
        cells = {k: row.get(k) for k in SWEEP_CSV_COLUMNS}
        if cells["windings"] is not None:
            cells["windings"] = "|".join(cells["windings"])
        if cells["tau_signs"] is not None:
            cells["tau_signs"] = "|".join(
                f"{c['cell']}:{','.join(str(x) for x in c['signs'])}" for c in cells["tau_signs"])
        writer.writerow([*(repr(float(row["lengths"][n])) for n in names),
                         *("" if v is None else v for v in cells.values())])
    return out.getvalue()
