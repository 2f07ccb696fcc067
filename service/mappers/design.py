"""Conversions of the design loop: splitting, design, robustness and critical-value maps."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Literal, TypedDict

import numpy as np

from engine.design.critical_values import SLICE_OPTIONS, Slice
from engine.design.design import Check, DesignResult, Target
from engine.design.robustness import Margin
from engine.design.slice_regions import Region
from engine.design.splitting import Split
from engine.design.surface_design import ConeTarget, SurfaceDesign
from engine.design.surface_splitting import ConeResolution, SurfaceSplit
from engine.local.critical import CriticalPoint
from engine.model.linkage import Linkage as EngineLinkage
from engine.model.tolerances import Tolerances as EngineTolerances
from engine.space.configuration_space import SpaceOptions
from engine.space.four_bar_cells import FourBarCell

#: Default margin of ``/v1/design/splitting``, relative to the median bar length.
from service.mappers.common import DEFAULT_MARGIN, json_int, positions_out, tolerances_out
from service.mappers.space import search_out
from service.schemas import common as c
from service.schemas import critical_values as cv_schemas
from service.schemas import design as design_schemas
from service.schemas import robustness as robustness_schemas
from service.schemas import splitting as splitting_schemas


def splitting_out(
    linkage: EngineLinkage, splits: list[Split], found: int, tol: EngineTolerances,
    crit: list[CriticalPoint], search: Mapping[str, object],
) -> splitting_schemas.SplittingResponse:
    return splitting_schemas.SplittingResponse(
        surface=None,
        branch_points=[
            splitting_schemas.BranchSplitOut(
                index=s.index,
                configuration=positions_out(linkage, linkage.positions_of(crit[s.index].u)),
                delta=s.delta,
                delta_linear=s.delta_linear,
                delta_error=s.delta_error,
                resolved=s.resolved,
                shift=s.shift.tolist(),
                sign=s.sign,
                connects=[list(p) for p in s.connects],
            )
            for s in splits
        ],
        critical_points_found=found,
        search=c.SearchReport.model_validate(search_out(search)),
        tolerances=tolerances_out(tol),
    )


def _cones_out(linkage: EngineLinkage, cones: list[ConeResolution]
               ) -> list[splitting_schemas.ConeSplitOut]:
    return [splitting_schemas.ConeSplitOut(
        configuration=positions_out(linkage, linkage.positions_of(c.point.u)),
        q_eigenvalues=np.asarray(c.point.analysis.q_eigenvalues).tolist(),
        delta=c.delta, delta_error=c.delta_error, sign=c.sign, sheets=c.sheets,
        euler_change=c.euler_change) for c in cones]


def surface_splitting_out(linkage: EngineLinkage, res: SurfaceSplit, tol: EngineTolerances
                          ) -> splitting_schemas.SplittingResponse:
    """A two-degree-of-freedom splitting answer (``surface``; no branch points)."""
    return splitting_schemas.SplittingResponse(
        surface=splitting_schemas.SurfaceSplitOut(
            cones=_cones_out(linkage, res.cones),
            predicted_euler_difference=res.predicted_euler_difference,
            euler=list(res.euler), betti_q=[list(b) if b else None for b in res.betti],
            critical_betti_q=list(res.critical_betti) if res.critical_betti else None,
            predicted_betti_q=[list(b) if b else None for b in res.predicted_betti],
            verified=res.verified, message=res.message),
        branch_points=[], critical_points_found=len(res.cones),
        search=c.SearchReport.model_validate(search_out(res.search)),
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
    options: SpaceOptions


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
    if body.options is not None and body.options.homotopy_paths_max is not None:
        opts["options"] = replace(SLICE_OPTIONS,
                                  homotopy_paths_max=body.options.homotopy_paths_max)
    return axes, opts


def design_in(body: design_schemas.DesignRequest) -> tuple[list[Target], list[str]]:
    """The targets and the adjustable bars of a design request."""
    return ([Target(t.branch_point, t.sign or 0) for t in body.targets],  # 0: refused
            list(body.adjustable))


def cone_targets_in(body: design_schemas.DesignRequest) -> list[ConeTarget]:
    """The targets of a two-degree-of-freedom design (cones asked for sheets or a sign)."""
    return [ConeTarget(t.branch_point, t.sheets or 0, t.sign or 0) for t in body.targets]


def design_margin(body: design_schemas.DesignRequest, linkage: EngineLinkage,
                  default: float = DEFAULT_MARGIN) -> float:
    """The required margin: the request's, else ``default`` of the median bar length (of the
    bars with a free end)."""
    if body.margin is not None:
        return body.margin
    return default * float(np.median(linkage.lengths[linkage.active]))


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
                delta_error=c.delta_error,
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
        surface=None,
        search=c.SearchReport.model_validate(search_out(search)),
        tolerances=tolerances_out(tol),
    )


def surface_design_out(linkage: EngineLinkage, res: SurfaceDesign, adjustable: list[str],
                       tol: EngineTolerances) -> design_schemas.DesignResponse:
    """A two-degree-of-freedom design answer (``surface``; no ``predicted``)."""
    r, split = res.result, res.split
    remeshed = split is not None and split.complete and res.cones_ended
    verified = None if split is None or not remeshed else bool(
        res.targets_met and split.verified)
    surface = None if split is None else design_schemas.SurfaceDesignOut(
        cones=_cones_out(linkage, split.cones), asked=[int(s) for s in res.signs],
        targets_met=res.targets_met, euler_change=res.euler_change,
        predicted_euler_difference=split.predicted_euler_difference,
        euler=list(split.euler), betti_q=[list(b) if b else None for b in split.betti],
        critical_betti_q=list(split.critical_betti) if split.critical_betti else None,
        predicted_betti_q=[list(b) if b else None for b in split.predicted_betti],
        remeshed_complete=remeshed, message=split.message)
    return design_schemas.DesignResponse(
        feasible=r.feasible,
        perturbation={bar: float(r.perturbation[linkage.bar_ids.index(bar)])
                      for bar in adjustable},
        largest_change=r.largest_change, predicted=[],
        conflicts=[design_schemas.ConflictOut(branch_points=c.branch_points, reason=c.reason)
                   for c in r.conflicts],
        verified=verified, surface=surface,
        search=c.SearchReport.model_validate(search_out(res.search)),
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
        guarantee_detail=res.guarantee_detail,
        exact_margin=None if res.exact_margin is None or not np.isfinite(res.exact_margin)
        else res.exact_margin,
        search=robustness_schemas.RobustnessSearch.model_validate(search_out(res.search)),
        tolerances=tolerances_out(tol),
    )


def critical_values_out(res: Slice, tol: EngineTolerances) -> cv_schemas.CriticalValuesResponse:
    return cv_schemas.CriticalValuesResponse(
        curves=[c.tolist() for c in res.curves],
        regions=[region_out(r) for r in res.regions],
        search=cv_schemas.SliceSearch.model_validate(search_out(res.search)),
        tolerances=tolerances_out(tol),
    )


def cell_signs_out(c: FourBarCell) -> cv_schemas.CellSigns:
    """One four-bar cell's tau signs (a map's region, a sweep's row)."""
    return cv_schemas.CellSigns.model_validate(
        {"cell": c.name, "bars": list(c.bars), "sides": list(c.sides), "signs": list(c.signs)})


def region_out(r: Region) -> cv_schemas.RegionOut:
    """A map's region with its label (:mod:`engine.design.region_labels`) where it was
    explored."""
    lab = r.label
    if lab is None:
        return cv_schemas.RegionOut(
            point=list(r.point), components=None if r.components is None
            else json_int(r.components), signature=r.signature, cells=r.cells,
            argument=r.argument)
    return cv_schemas.RegionOut(
        point=list(r.point), components=None if r.components is None else json_int(r.components),
        signature=r.signature, cells=r.cells,
        argument=r.argument, components_exact=lab.components_exact,
        components_traced=lab.traced, components_rule=lab.components_rule,
        tau_signs=[cell_signs_out(c) for c in lab.cells] or None,
        gated=lab.gated, gated_reason=lab.gated_reason, windings=list(lab.windings))
