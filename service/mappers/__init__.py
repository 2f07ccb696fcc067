"""The only place that converts between HTTP schemas and engine types."""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, TypedDict

import numpy as np
import pybase64
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ValidationError

from engine.catalogue.presets import PRESETS, build_preset
from engine.design.critical_values import Slice
from engine.design.design import Check, DesignResult, Target
from engine.design.robustness import Margin
from engine.design.splitting import Split
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
from engine.local.critical import CriticalPoint
from engine.local.prestress import PrestressResult
from engine.local.rigidity import RigidityResult
from engine.local.rigidity import TangentForm as EngineTangentForm
from engine.local.second_order import SecondOrderResult
from engine.model.constraints import ProjectionResult
from engine.model.errors import InvalidParameter, InvalidRequest, UnknownPreset
from engine.model.linkage import Limits, build_linkage
from engine.model.linkage import Linkage as EngineLinkage
from engine.model.tolerances import Tolerances as EngineTolerances
from engine.model.tolerances import check_residual_scale, check_resolution, scaled_tolerances
from engine.model.vectors import normalised
from engine.space.configuration_space import (
    Component,
    CriticalSearch,
    SpaceOptions,
    SpaceResult,
    positions_along,
    rotor_angles,
    winding,
)
from engine.space.trace import TraceOptions
from service.gcpause import gc_paused
from service.schemas import common as c
from service.schemas import critical_values as cv_schemas
from service.schemas import design as design_schemas
from service.schemas import jobs as job_schemas
from service.schemas import robustness as robustness_schemas
from service.schemas import space
from service.schemas import splitting as splitting_schemas
from service.schemas.analysis import (
    DualCertificate,
    RigidityResponse,
    SecondOrderFlex,
    SecondOrderResponse,
    StressCertificate,
    TangentForm,
)
from service.schemas.presets import PresetInfo

if TYPE_CHECKING:  # service.tasks maps its sweeps here
    from service.tasks import Job

#: Default margin of ``/v1/design/splitting``, relative to the median bar length.
DEFAULT_MARGIN = 1e-4


def linkage_in(model: c.Linkage, limits: Limits) -> EngineLinkage:
    """Request linkage -> validated engine linkage (raises EngineError with field locations)."""
    # The request models have the fields of VertexSpec and BarSpec: passed as they are, since
    # copying 20,000 of them into dataclasses costs more than the whole check.
    with gc_paused():
        return build_linkage(model.dimension, model.vertices, model.bars, limits)


def problem_in(
    linkage: c.Linkage, tolerances: c.Tolerances | None, limits: Limits
) -> tuple[EngineLinkage, EngineTolerances]:
    """Request linkage and tolerances -> validated engine linkage and the tolerances to use:
    those given, else the defaults, with ``residual_atol`` scaled to the linkage's median bar
    length. Positions that float64 cannot resolve to that tolerance are refused."""
    engine_linkage = linkage_in(linkage, limits)
    given = tolerances.model_dump(exclude_none=True) if tolerances else {}
    lengths = engine_linkage.lengths
    scale = float(np.median(lengths)) if lengths.size else 1.0
    tol = scaled_tolerances(scale, **given)
    check_residual_scale(tol, scale)
    check_resolution(engine_linkage.positions, tol)
    return engine_linkage, tol


def tolerances_out(tol: EngineTolerances) -> c.TolerancesUsed:
    return c.TolerancesUsed(
        rank_rtol=tol.rank_rtol, residual_atol=tol.residual_atol, q_rtol=tol.q_rtol
    )


def _fixed_out(mask: np.ndarray) -> bool | list[bool]:
    if mask.all():
        return True
    if not mask.any():
        return False
    return [bool(b) for b in mask]


def linkage_out(linkage: EngineLinkage) -> c.Linkage:
    """Engine linkage -> response linkage (lengths always explicit)."""
    return c.Linkage(
        dimension=linkage.dimension,  # type: ignore[arg-type]
        vertices=[
            c.Vertex(id=vid, position=pos.tolist(), fixed=_fixed_out(mask))
            for vid, pos, mask in zip(
                linkage.vertex_ids, linkage.positions, linkage.fixed, strict=True
            )
        ],
        bars=[
            c.Bar(id=bid, ends=[linkage.vertex_ids[i], linkage.vertex_ids[j]], length=float(ln))
            for bid, (i, j), ln in zip(linkage.bar_ids, linkage.ends, linkage.lengths, strict=True)
        ],
    )


def vertex_vectors(linkage: EngineLinkage, v: np.ndarray) -> c.VertexVectors:
    """Free-coordinate vector (M,) -> normalised ``{vertex_id: [..]}`` (fixed axes 0)."""
    lifted = linkage.vertex_vectors(normalised(v))
    return dict(zip(linkage.vertex_ids, lifted.tolist(), strict=True))


def positions_out(linkage: EngineLinkage, positions: np.ndarray) -> c.VertexVectors:
    return dict(zip(linkage.vertex_ids, positions.tolist(), strict=True))


def bar_values(linkage: EngineLinkage, v: np.ndarray) -> c.BarValues:
    """Per-bar vector (E,) -> normalised ``{bar_id: value}``."""
    return dict(zip(linkage.bar_ids, normalised(v).tolist(), strict=True))


def _projection_fields(linkage: EngineLinkage, proj: ProjectionResult) -> dict[str, object]:
    return {
        "projection_residual": proj.residual,
        "input_residual": proj.input_residual,
        "projection_distance": proj.distance,
        "configuration": positions_out(linkage, proj.positions),
    }


def _tangent_form_out(linkage: EngineLinkage, tf: EngineTangentForm | None) -> TangentForm | None:
    if tf is None:
        return None
    vector = normalised(tf.direction)
    # t = |t| * direction and vector = +-direction: the sign is the orientation.
    orientation = int(np.sign(vector @ tf.direction)) if tf.orientation != 0 else 0
    return TangentForm.model_construct(
        vector=vertex_vectors(linkage, vector),
        orientation=orientation,
        log10_magnitude=(
            float(tf.log10_magnitude) if math.isfinite(tf.log10_magnitude) else None
        ),
    )


def rigidity_out(
    linkage: EngineLinkage, rig: RigidityResult, proj: ProjectionResult
) -> RigidityResponse:
    """Built without validation (``model_construct``): every field is made here from engine
    arrays with the schema's Python types, and validating the per-vertex dictionaries of a
    10,000-rotor chain again would cost more than the analysis (a test checks that the result
    validates and serialises identically)."""
    with gc_paused():
        return _rigidity_response(linkage, rig, proj)


def _rigidity_response(
    linkage: EngineLinkage, rig: RigidityResult, proj: ProjectionResult
) -> RigidityResponse:
    return RigidityResponse.model_construct(
        rank=int(rig.rank),
        n_free=int(rig.n_free),
        n_constraints=int(rig.n_constraints),
        expected_dof=int(rig.expected_dof),
        dof=int(rig.dof),
        critical=bool(rig.critical),
        singular_values=rig.singular_values.tolist(),
        singular_values_complete=bool(rig.singular_values_complete),
        zero_modes=[vertex_vectors(linkage, z) for z in rig.zero_modes],
        trivial_motions=int(rig.trivial_motions),
        self_stresses=[bar_values(linkage, s) for s in rig.self_stresses],
        tangent_form=_tangent_form_out(linkage, rig.tangent_form),
        method=str(rig.method),
        tolerances=tolerances_out(rig.tolerances),
        projection_residual=float(proj.residual),
        input_residual=float(proj.input_residual),
        projection_distance=float(proj.distance),
        configuration=positions_out(linkage, proj.positions),
    )


def second_order_out(
    linkage: EngineLinkage, res: SecondOrderResult, proj: ProjectionResult
) -> SecondOrderResponse:
    return SecondOrderResponse(
        kind=res.kind,
        reason=res.reason,
        critical=res.rigidity.critical,
        self_stress=None if res.self_stress is None else bar_values(linkage, res.self_stress),
        zero_modes=[vertex_vectors(linkage, z) for z in res.zero_modes],
        q=None if res.q is None else res.q.tolist(),
        q_eigenvalues=None if res.q_eigenvalues is None else res.q_eigenvalues.tolist(),
        tangents=[vertex_vectors(linkage, t) for t in res.tangents],
        tangent_coefficients=res.tangent_coefficients.tolist(),
        prestress_stable=res.prestress.prestress_stable,
        second_order_rigid=res.prestress.second_order_rigid,
        stability_reason=res.prestress.reason,
        certificate=_certificate_out(linkage, res.prestress),
        second_order_flex=_second_order_flex_out(linkage, res.prestress),
        tolerances=tolerances_out(res.rigidity.tolerances),
        **_projection_fields(linkage, proj),  # type: ignore[arg-type]
    )


def _raw_vertex_vectors(linkage: EngineLinkage, v: np.ndarray) -> c.VertexVectors:
    """As :func:`vertex_vectors` without renormalising: certificates are written in this exact
    basis and scale (a sign flip would change the dual matrix or the sign of the energy)."""
    return dict(zip(linkage.vertex_ids, linkage.vertex_vectors(v).tolist(), strict=True))


def _certificate_out(
    linkage: EngineLinkage, pre: PrestressResult
) -> StressCertificate | DualCertificate | None:
    if pre.prestress_stable and pre.stress is not None:
        return StressCertificate(
            stress=dict(zip(linkage.bar_ids, pre.stress.tolist(), strict=True)),
            min_eigenvalue=pre.min_eigenvalue,
        )
    if pre.prestress_stable is False and pre.dual is not None:
        return DualCertificate(
            dual=pre.dual.tolist(),
            flexes=[_raw_vertex_vectors(linkage, f) for f in pre.flexes],
            dual_residual=float(pre.dual_residual or 0.0),
        )
    return None


def _second_order_flex_out(linkage: EngineLinkage, pre: PrestressResult) -> SecondOrderFlex | None:
    if pre.second_order_flex is None or pre.second_order_acceleration is None:
        return None
    return SecondOrderFlex(
        velocity=_raw_vertex_vectors(linkage, pre.second_order_flex),
        acceleration=_raw_vertex_vectors(linkage, pre.second_order_acceleration),
    )


def preset_overrides_in(query: Iterable[tuple[str, str]]) -> dict[str, float]:
    """A preset's parameters from a query string, each a number (the engine names unknown
    parameters and values that give no valid linkage)."""
    overrides: dict[str, float] = {}
    for key, raw in query:
        try:
            overrides[key] = float(raw)
        except ValueError:
            raise InvalidParameter(f"not a number: {raw!r}", loc=(key,)) from None
    return overrides


def presets_out() -> list[PresetInfo]:
    return [
        PresetInfo(
            name=p.name, description=p.description, parameters=dict(p.parameters),
            dimension=p.dimension,
        )
        for p in PRESETS.values()
    ]


# -- configuration space family --------------------------------------------------------------


def space_options_in(model: space.SpaceOptions | None) -> SpaceOptions:
    # the time budget goes to the deadline, ``points`` to the answer's mapping (space_out)
    given = model.model_dump(exclude_none=True, exclude={"time_budget_s", "points"}) \
        if model else {}
    trace_keys = {"max_points", "strain_tol", "step_max"}
    trace = TraceOptions(**{k: v for k, v in given.items() if k in trace_keys})
    return SpaceOptions(trace=trace, **{k: v for k, v in given.items() if k not in trace_keys})


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


def sweep_in(body: job_schemas.SweepRequest, limits: Limits) -> SweepJob:
    """Validate a sweep (names, lengths, limits) before any point is analysed; an unknown
    bar or parameter is an error of the request, at ``grid``/``samples``."""
    axes_loc = "grid" if body.grid is not None else "samples"
    names = tuple(body.grid or body.samples or {})
    family: Family
    try:
        if body.linkage is not None:
            linkage, tol = problem_in(body.linkage, body.tolerances, limits)
            family = BarFamily(linkage, names)
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
        points = grid_points([GridAxis(k, a.min, a.max, a.steps) for k, a in body.grid.items()])
    else:
        assert body.samples is not None and body.count is not None
        points = sample_points([SampleAxis(k, a.mean, a.sd) for k, a in body.samples.items()],
                               body.count, body.seed)
    compute = tuple(c for c in COMPUTE if c in body.compute)
    return SweepJob(family, points, compute, tol, space_options_in(body.options), names)


def sweep_out(names: tuple[str, ...], rows: list[PointResult]) -> job_schemas.SweepResult:
    s = summarize(rows)
    return job_schemas.SweepResult(
        rows=[
            job_schemas.SweepRow(
                lengths=dict(zip(names, r.values, strict=True)),
                components=r.components,
                complete=r.complete,
                critical_points=r.critical_points,
                margin=r.margin,
                windings=None if r.windings is None else list(r.windings),
                gated=r.gated,
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


def job_out(job: Job, expires: float | None) -> job_schemas.JobOut:
    return job_schemas.JobOut(
        id=job.id,
        operation=job.operation,
        status=job.status,  # type: ignore[arg-type]
        progress=job_schemas.Progress(fraction=job.fraction, message=job.message),
        created=job.created,
        started=job.started,
        finished=job.finished,
        expires=expires,
        result=job.result,
        error=None if job.error is None else job_schemas.JobError(**job.error),
    )


#: Columns of a sweep's CSV after the swept names, in this order.
SWEEP_CSV_COLUMNS = ("components", "complete", "critical_points", "margin", "gated", "windings",
                     "error")


def sweep_csv(result: dict[str, Any]) -> str:
    """A sweep's rows as CSV: one row per point, the swept values first (empty cells where a
    value was not computed; windings joined by ``|``)."""
    rows = result["rows"]
    names = list(rows[0]["lengths"]) if rows else []
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([*names, *SWEEP_CSV_COLUMNS])
    for row in rows:
        cells = {k: row.get(k) for k in SWEEP_CSV_COLUMNS}
        if cells["windings"] is not None:
            cells["windings"] = "|".join(cells["windings"])
        writer.writerow([*(repr(float(row["lengths"][n])) for n in names),
                         *("" if v is None else v for v in cells.values())])
    return out.getvalue()


def _critical_out(linkage: EngineLinkage, k: int, cp: CriticalPoint) -> space.CriticalPointOut:
    res = cp.analysis
    return space.CriticalPointOut(
        index=k,
        configuration=positions_out(linkage, linkage.positions_of(cp.u)),
        kind=res.kind,
        reason=res.reason,
        self_stress=None if res.self_stress is None else bar_values(linkage, res.self_stress),
        zero_modes=[vertex_vectors(linkage, z) for z in res.zero_modes],
        q_eigenvalues=None if res.q_eigenvalues is None else res.q_eigenvalues.tolist(),
        tangents=[vertex_vectors(linkage, t) for t in res.tangents],
        residual=cp.length_residual,
        stress_residual=cp.stress_residual,
    )


def _search_out(search: Mapping[str, object]) -> dict[str, object]:
    return {k: (v.item() if isinstance(v, np.generic) else v) for k, v in search.items()}


def critical_list_out(
    linkage: EngineLinkage, crit: list[CriticalPoint]
) -> list[space.CriticalPointOut]:
    """The critical points as answered (indexed in the order found)."""
    return [_critical_out(linkage, k, cp) for k, cp in enumerate(crit)]


def critical_points_out(
    linkage: EngineLinkage,
    res: SpaceResult | CriticalSearch,
    proj: ProjectionResult,
    tol: EngineTolerances,
) -> space.CriticalPointsResponse:
    return space.CriticalPointsResponse(
        critical_points=critical_list_out(linkage, res.critical_points),
        near_misses=[
            space.NearMissOut(
                configuration=positions_out(linkage, linkage.positions_of(m.u)),
                singular_gap=m.singular_gap,
                distance=m.distance,
                length_gap=m.length_gap,
                critical_configuration=positions_out(linkage, linkage.positions_of(m.critical_u)),
            )
            for m in res.near_misses
        ],
        degenerate=res.degenerate,
        search=c.SearchReport.model_validate(_search_out(res.search)),
        tolerances=tolerances_out(tol),
        **_projection_fields(linkage, proj),  # type: ignore[arg-type]
    )


def packed_array(ids: list[str], values: np.ndarray) -> space.PackedArray:
    """``values`` (n, len(ids), ...) as a PackedArray: little-endian float64, C order, base64
    (pybase64's SIMD encoder, straight to a str: some 2 ms for 10 MB, the standard library's
    ``base64.b64encode(...).decode()`` some 25 ms)."""
    data = np.ascontiguousarray(values, dtype="<f8")
    return space.PackedArray.model_construct(
        ids=list(ids), shape=list(data.shape), dtype="<f8",
        base64=pybase64.b64encode_as_string(data.data))


def _component_out(
    linkage: EngineLinkage, comp: Component, compact: bool = False
) -> space.ComponentOut:
    pos = positions_along(linkage, comp.points)  # (n, V, d), all points at once
    angles = rotor_angles(linkage, comp.points, pos)  # {bar: (n,)}
    positions: dict[str, list[list[float]]] | space.PackedArray
    angles_out: dict[str, list[float]] | space.PackedArray
    if compact:
        positions = packed_array(list(linkage.vertex_ids), pos)
        walk = np.stack(list(angles.values()), axis=1) if angles else np.empty((len(pos), 0))
        angles_out = packed_array(list(angles), walk)  # (n, R)
    else:
        positions = {vid: pos[:, k].tolist() for k, vid in enumerate(linkage.vertex_ids)}
        angles_out = {bar: a.tolist() for bar, a in angles.items()}
    # Built without validation: every field is already of its exact type (bools, ints and
    # Python floats from ``tolist``), and validating ~10^6 floats would cost more than the
    # engine's answer (see bench/bench_points.py).
    return space.ComponentOut.model_construct(
        closed=comp.closed,
        through_start=comp.through_start,
        positions=positions,
        angles=angles_out,
        winding={bar: winding(a, comp.closed) for bar, a in angles.items()},
        critical_points=[int(k) for k in comp.critical_points],
    )


def space_out(
    linkage: EngineLinkage, res: SpaceResult, proj: ProjectionResult, tol: EngineTolerances,
    points: str | None = None,
) -> space.SpaceResponse:
    """The configuration-space answer; ``points`` is ``options.points`` ("compact": each
    component's positions and angles as PackedArrays)."""
    owner = {s: k for k, comp in enumerate(res.components) for s in comp.segments}
    compact = points == "compact"
    with gc_paused():  # ~10^6 floats and lists for 10^5 points
        components = [_component_out(linkage, c, compact) for c in res.components]
    return space.SpaceResponse(
        components=components,
        critical_points=critical_list_out(linkage, res.critical_points),
        segments=[
            space.SegmentOut.model_validate(
                {"from": s.start, "to": s.end, "component": owner.get(k, -1),
                 "from_ray": s.start_ray, "to_ray": s.end_ray}
            )
            for k, s in enumerate(res.segments)
        ],
        degenerate=res.degenerate,
        search=c.SearchReport.model_validate(_search_out(res.search)),
        tolerances=tolerances_out(tol),
        **_projection_fields(linkage, proj),  # type: ignore[arg-type]
    )


def splitting_out(
    linkage: EngineLinkage, splits: list[Split], found: int, tol: EngineTolerances,
    crit: list[CriticalPoint], search: Mapping[str, object],
) -> splitting_schemas.SplittingResponse:
    return splitting_schemas.SplittingResponse(
        branch_points=[
            splitting_schemas.BranchSplitOut(
                index=s.index,
                configuration=positions_out(linkage, linkage.positions_of(crit[s.index].u)),
                delta=s.delta,
                delta_linear=s.delta_linear,
                shift=s.shift.tolist(),
                sign=s.sign,
                connects=[list(p) for p in s.connects],
            )
            for s in splits
        ],
        critical_points_found=found,
        search=c.SearchReport.model_validate(_search_out(search)),
        tolerances=tolerances_out(tol),
    )


def robustness_in(
    body: robustness_schemas.RobustnessRequest,
) -> tuple[list[str] | None, Literal["auto", "closed-form", "multistart"]]:
    """The adjustable bars (None: every bar with a free end) and the method (default auto)."""
    adjustable = None if body.adjustable is None else list(body.adjustable)
    return adjustable, body.method or "auto"


class SliceOptions(TypedDict, total=False):
    """Keyword arguments of :func:`engine.design.critical_values.critical_value_slice` that a
    request
    may set (those it leaves out keep the engine's defaults)."""

    resolution: int
    seeds_per_axis: int


def critical_values_in(
    body: cv_schemas.CriticalValuesRequest,
) -> tuple[list[tuple[str, float, float]], SliceOptions]:
    """The slice's axes ``(bar, min, max)`` and the options the request sets; its time budget
    goes to the deadline, not to the slice."""
    axes = [(a.bar, a.min, a.max) for a in body.axes]
    opts = SliceOptions()
    if body.options is not None and body.options.resolution is not None:
        opts["resolution"] = body.options.resolution
    if body.options is not None and body.options.seeds_per_axis is not None:
        opts["seeds_per_axis"] = body.options.seeds_per_axis
    return axes, opts


def design_in(body: design_schemas.DesignRequest) -> tuple[list[Target], list[str]]:
    """The targets and the adjustable bars of a design request."""
    return [Target(t.branch_point, t.sign) for t in body.targets], list(body.adjustable)


def design_margin(body: design_schemas.DesignRequest, linkage: EngineLinkage) -> float:
    """The required margin: the request's, else ``DEFAULT_MARGIN`` of the median bar length
    (of the bars with a free end)."""
    if body.margin is not None:
        return body.margin
    return DEFAULT_MARGIN * float(np.median(linkage.lengths[linkage.active]))


def design_out(
    linkage: EngineLinkage,
    result: DesignResult,
    adjustable: list[str],
    checks: list[Check],
    tol: EngineTolerances,
    search: Mapping[str, object],
) -> design_schemas.DesignResponse:
    return design_schemas.DesignResponse(
        feasible=result.feasible,
        perturbation={
            bar: float(result.perturbation[linkage.bar_ids.index(bar)]) for bar in adjustable
        },
        largest_change=result.largest_change,
        predicted=[
            design_schemas.PredictedOut(
                branch_point=c.branch_point,
                sign=c.sign,
                delta=c.delta,
                connects=[list(p) for p in c.connects],
                traced_connects=None if c.traced is None else [list(p) for p in c.traced],
            )
            for c in checks
        ],
        conflicts=[
            design_schemas.ConflictOut(branch_points=c.branch_points, reason=c.reason)
            for c in result.conflicts
        ],
        verified=all(c.agrees for c in checks) if checks and not any(c.skipped for c in checks)
        else None,
        search=c.SearchReport.model_validate(_search_out(search)),
        tolerances=tolerances_out(tol),
    )


def robustness_out(
    linkage: EngineLinkage, res: Margin, tol: EngineTolerances
) -> robustness_schemas.RobustnessResponse:
    return robustness_schemas.RobustnessResponse(
        margin=res.margin if np.isfinite(res.margin) else None,
        nearest=dict(zip(linkage.bar_ids, res.nearest.tolist(), strict=True)),
        critical_configuration=positions_out(linkage, linkage.positions_of(res.critical_u)),
        starts=res.starts,
        converged=res.converged,
        success=res.success,
        message=res.message,
        method=res.method,
        guarantee=res.guarantee,
        search=robustness_schemas.RobustnessSearch.model_validate(_search_out(res.search)),
        tolerances=tolerances_out(tol),
    )


def critical_values_out(res: Slice, tol: EngineTolerances) -> cv_schemas.CriticalValuesResponse:
    return cv_schemas.CriticalValuesResponse(
        curves=[c.tolist() for c in res.curves],
        regions=[
            cv_schemas.RegionOut(point=list(r.point), components=r.components,
                                 signature=r.signature, cells=r.cells)
            for r in res.regions
        ],
        search=cv_schemas.SliceSearch.model_validate(_search_out(res.search)),
        tolerances=tolerances_out(tol),
    )
