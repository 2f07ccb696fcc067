"""Conversions of configuration-space searches (options in; critical points, components out)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from engine.local.critical import CriticalPoint
from engine.model.constraints import ProjectionResult
from engine.model.linkage import Linkage as EngineLinkage
from engine.model.tolerances import Tolerances as EngineTolerances
from engine.space.configuration_space import (
    Component,
    CriticalSearch,
    SpaceOptions,
    SpaceResult,
    positions_along,
    rotor_angles,
    winding,
)
from engine.space.surfaces.explore import SurfaceOptions, SurfaceResult
from engine.space.trace import TraceOptions
from service.gcpause import gc_paused

#: Default margin of ``/v1/design/splitting``, relative to the median bar length.
from service.mappers.analysis import projection_fields
from service.mappers.common import (
    bar_values,
    json_int,
    packed_array,
    positions_out,
    tolerances_out,
    vertex_vectors,
)
from service.schemas import common as c
from service.schemas import space


def space_options_in(model: space.SpaceOptions | None) -> SpaceOptions:
    # the time budget goes to the deadline, ``points`` to the answer's mapping (space_out)
    given = model.model_dump(exclude_none=True, exclude={
        "time_budget_s", "points", "surface_step", "max_triangles"}) if model else {}
    trace_keys = {"max_points", "strain_tol", "step_max"}
    trace = TraceOptions(**{k: v for k, v in given.items() if k in trace_keys})
    return SpaceOptions(trace=trace, **{k: v for k, v in given.items() if k not in trace_keys})


def surface_options_in(model: space.SpaceOptions | None) -> SurfaceOptions:
    """The options of a two-degree-of-freedom search (``surface_step``, ``max_triangles``,
    ``random_starts``, ``homotopy_paths_max``, ``seed``; the rest are the tracer's)."""
    if model is None:
        return SurfaceOptions()
    given: dict[str, Any] = {"step_rel": model.surface_step, "max_triangles": model.max_triangles,
             "random_starts": model.random_starts,
             "homotopy_paths_max": model.homotopy_paths_max, "seed": model.seed}
    return SurfaceOptions(**{k: v for k, v in given.items() if v is not None})


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


def search_out(search: Mapping[str, object]) -> dict[str, object]:
    """A search report as JSON data: numpy scalars as Python's, integers beyond
    ``MAX_JSON_INT`` (e.g. ``components_total``, a homotopy's ``paths``: 2^199 for a 100-rotor
    chain) as decimal strings, inside nested objects and lists too."""
    return {k: _json_value(v) for k, v in search.items()}


def _json_value(v: object) -> object:
    value = v.item() if isinstance(v, np.generic) else v
    if isinstance(value, int) and not isinstance(value, bool):
        return json_int(value)
    if isinstance(value, Mapping):
        return {k: _json_value(x) for k, x in value.items()}
    if isinstance(value, list | tuple):
        return [_json_value(x) for x in value]
    return value


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
        search=c.SearchReport.model_validate(search_out(res.search)),
        tolerances=tolerances_out(tol),
        **projection_fields(linkage, proj),  # type: ignore[arg-type]
    )


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
        search=c.SearchReport.model_validate(search_out(res.search)),
        tolerances=tolerances_out(tol),
        **projection_fields(linkage, proj),  # type: ignore[arg-type]
    )


def surfaces_out(
    linkage: EngineLinkage, res: SurfaceResult, proj: ProjectionResult, tol: EngineTolerances,
    points: str | None = None,
) -> space.SpaceResponse:
    """The configuration-space answer of a two-degree-of-freedom linkage: its surfaces."""
    surfaces = []
    with gc_paused():
        for comp in res.components:
            pos = np.array([linkage.positions_of(u) for u in comp.vertices]).reshape(
                len(comp.vertices), linkage.n_vertices, linkage.dimension)
            positions: dict[str, list[list[float]]] | space.PackedArray = (
                packed_array(list(linkage.vertex_ids), pos) if points == "compact" else
                {vid: pos[:, k].tolist() for k, vid in enumerate(linkage.vertex_ids)})
            h = comp.homology
            surfaces.append(space.SurfaceOut(
                closed=comp.closed, positions=positions, triangles=comp.triangles.tolist(),
                euler=None if h is None else h.euler,
                orientable=None if h is None else h.orientable,
                betti_z2=None if h is None else list(h.betti_z2),
                betti_q=None if h is None else list(h.betti_q),
                genus=None if h is None or not comp.closed or len(comp.apexes) else h.genus,
                defects=comp.defects, inverted_triangles=comp.inverted,
                tangent_angle_max=float(np.degrees(comp.tangent_angle_max)),
                morse_sum=comp.morse_sum, morse_agrees=comp.morse_agrees,
                critical_points=comp.critical_points, apexes=comp.apexes.tolist()))
    heights = [space.HeightCriticalOut(
        configuration=positions_out(linkage, linkage.positions_of(u)), index=int(i),
        surface=int(k)) for u, i, k in zip(res.height_critical.points, res.height_critical.index,
                                           res.height_component, strict=True)]
    search = {**res.search.as_dict(), "height": vertex_vectors(linkage, res.height)}
    return space.SpaceResponse(
        components=[], critical_points=critical_list_out(linkage, res.critical_points),
        segments=[], degenerate=bool(res.search.degenerate), surfaces=surfaces,
        height_critical_points=heights,
        search=c.SearchReport.model_validate(search_out(search)),
        tolerances=tolerances_out(tol),
        **projection_fields(linkage, proj),  # type: ignore[arg-type]
    )
