"""The only place that converts between HTTP schemas and engine types."""

from __future__ import annotations

import math

import numpy as np

from engine.constraints import ProjectionResult
from engine.linkage import BarSpec, Limits, VertexSpec, build_linkage
from engine.linkage import Linkage as EngineLinkage
from engine.presets import PRESETS
from engine.rigidity import RigidityResult
from engine.rigidity import TangentForm as EngineTangentForm
from engine.second_order import SecondOrderResult
from engine.tolerances import Tolerances as EngineTolerances
from engine.vectors import normalised
from service.schemas import common as c
from service.schemas.analysis import (
    RigidityResponse,
    SecondOrderResponse,
    TangentForm,
)
from service.schemas.presets import PresetInfo


def linkage_in(model: c.Linkage, limits: Limits) -> EngineLinkage:
    """Request linkage -> validated engine linkage (raises EngineError with field locations)."""
    return build_linkage(
        model.dimension,
        [VertexSpec(v.id, v.position, v.fixed) for v in model.vertices],
        [BarSpec(b.id, b.ends, b.length) for b in model.bars],
        limits,
    )


def tolerances_in(model: c.Tolerances | None) -> EngineTolerances:
    """Request tolerances -> engine tolerances (defaults where unset)."""
    given = model.model_dump(exclude_none=True) if model else {}
    return EngineTolerances(**given)


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
    return TangentForm(
        vector=vertex_vectors(linkage, vector),
        orientation=orientation,
        log10_magnitude=tf.log10_magnitude if math.isfinite(tf.log10_magnitude) else None,
    )


def rigidity_out(
    linkage: EngineLinkage, rig: RigidityResult, proj: ProjectionResult
) -> RigidityResponse:
    return RigidityResponse(
        rank=rig.rank,
        n_free=rig.n_free,
        n_constraints=rig.n_constraints,
        expected_dof=rig.expected_dof,
        dof=rig.dof,
        critical=rig.critical,
        singular_values=rig.singular_values.tolist(),
        singular_values_complete=rig.singular_values_complete,
        zero_modes=[vertex_vectors(linkage, z) for z in rig.zero_modes],
        trivial_motions=rig.trivial_motions,
        self_stresses=[bar_values(linkage, s) for s in rig.self_stresses],
        tangent_form=_tangent_form_out(linkage, rig.tangent_form),
        method=rig.method,
        tolerances=tolerances_out(rig.tolerances),
        **_projection_fields(linkage, proj),  # type: ignore[arg-type]
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
        tolerances=tolerances_out(res.rigidity.tolerances),
        **_projection_fields(linkage, proj),  # type: ignore[arg-type]
    )


def presets_out() -> list[PresetInfo]:
    return [
        PresetInfo(name=p.name, description=p.description, parameters=dict(p.parameters))
        for p in PRESETS.values()
    ]
