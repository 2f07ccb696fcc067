"""Conversions of the first- and second-order analyses (rigidity, second order, prestress)."""

from __future__ import annotations

import math

import numpy as np

from engine.local.prestress import PrestressResult
from engine.local.rigidity import RigidityResult
from engine.local.rigidity import TangentForm as EngineTangentForm
from engine.local.second_order import SecondOrderResult
from engine.model.constraints import ProjectionResult
from engine.model.linkage import Linkage as EngineLinkage
from engine.model.vectors import normalised
from service.gcpause import gc_paused

#: Default margin of ``/v1/design/splitting``, relative to the median bar length.
from service.mappers.common import (
    _raw_vertex_vectors,
    bar_values,
    positions_out,
    tolerances_out,
    vertex_vectors,
)
from service.schemas.analysis import (
    DualCertificate,
    RigidityResponse,
    SecondOrderFlex,
    SecondOrderResponse,
    StressCertificate,
    TangentForm,
)


def projection_fields(linkage: EngineLinkage, proj: ProjectionResult) -> dict[str, object]:
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
        **projection_fields(linkage, proj),  # type: ignore[arg-type]
    )


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
