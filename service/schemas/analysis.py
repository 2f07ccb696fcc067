"""Responses of the analysis endpoints."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from service.schemas.common import BarValues, TolerancesUsed, VertexVectors


class Projection(BaseModel):
    projection_residual: float = Field(
        description="largest |l - L| at the analysed configuration (after projection)"
    )
    input_residual: float = Field(description="largest |l - L| at the positions as given")
    projection_distance: float = Field(
        description="2-norm of the move from the given positions to the analysed configuration"
    )
    configuration: VertexVectors = Field(description="the analysed configuration")


class TangentForm(BaseModel):
    vector: VertexVectors = Field(description="t / |t|, normalised by the vector convention")
    orientation: int = Field(
        description="+1 or -1: t = orientation * 10**log10_magnitude * vector; 0 at a critical "
        "point. Relative to the order of vertices and bars in the request."
    )
    log10_magnitude: float | None = Field(description="log10 |t|; null where t = 0")


class RigidityResponse(Projection):
    rank: int
    n_free: int = Field(description="M, the number of free coordinates")
    n_constraints: int = Field(description="E, the number of bars with a free end")
    expected_dof: int = Field(description="M - E - trivial_motions")
    dof: int = Field(description="number of nontrivial zero modes")
    critical: bool = Field(description="J has lower rank than min(E, M - trivial_motions)")
    singular_values: list[float] = Field(description="of J, descending")
    singular_values_complete: bool = Field(
        description="false for large linkages: only the largest and the smallest are computed"
    )
    zero_modes: list[VertexVectors]
    trivial_motions: int = Field(description="number of rigid motions counted apart")
    self_stresses: list[BarValues]
    tangent_form: TangentForm | None = Field(
        description="for M - E = 1 (one degree of freedom, something fixed)"
    )
    method: str
    tolerances: TolerancesUsed


class StressCertificate(BaseModel):
    stress: BarValues = Field(
        description="the combined self-stress omega (unit 2-norm, 0 on inert bars, sign as "
        "computed): its energy sum_a omega_a Hess(l_a^2) is positive definite on the flexes"
    )
    min_eigenvalue: float | None = Field(
        description="smallest eigenvalue of that energy on the orthonormal flexes (null when "
        "there is no non-trivial flex)"
    )


class DualCertificate(BaseModel):
    dual: list[list[float]] = Field(
        description="X, positive semidefinite with trace 1, in the basis `flexes`, with "
        "<Q_k, X> = 0 for every self-stress: no stress combination is definite"
    )
    flexes: list[VertexVectors] = Field(
        description="orthonormal basis of the non-trivial flexes in which X is written"
    )
    dual_residual: float = Field(
        description="max over a basis of unit self-stresses w_k of |<Q_k, X>| / (4 |w_k|_1)"
    )


class SecondOrderFlex(BaseModel):
    velocity: VertexVectors = Field(
        description="p', a unit non-trivial flex with zero energy under every self-stress"
    )
    acceleration: VertexVectors = Field(
        description="p'' with J p'' = -(p'^T Hess(l_a^2) p')_a (minimal norm): (p', p'') is a "
        "second-order flex"
    )


class SecondOrderResponse(Projection):
    kind: Literal["regular", "branch", "rigid", "degenerate"]
    reason: str | None = Field(description="why the point is degenerate")
    critical: bool
    self_stress: BarValues | None
    zero_modes: list[VertexVectors] = Field(
        description="basis of the nontrivial zero modes; at a critical point the eigenvectors of "
        "Q, ordered by decreasing eigenvalue"
    )
    q: list[list[float]] | None = Field(
        description="Q = sum_a sigma_a Hess(l_a^2) on zero_modes"
    )
    q_eigenvalues: list[float] | None
    tangents: list[VertexVectors] = Field(
        description="branch directions; for one degree of freedom two lines t0, t1, i.e. the "
        "four rays +t0, -t0, +t1, -t1 numbered 0..3"
    )
    tangent_coefficients: list[list[float]] = Field(
        description="the tangents as coefficients on zero_modes"
    )
    prestress_stable: bool | None = Field(
        description="a combination of self-stresses has positive definite energy on the "
        "non-trivial flexes (null: undecided, see stability_reason)"
    )
    second_order_rigid: bool | None = Field(
        description="no non-trivial flex extends to a second-order flex (Connelly-Whiteley); "
        "null: undecided"
    )
    stability_reason: str = Field(
        description="what the certificates prove and which case is undecided"
    )
    certificate: StressCertificate | DualCertificate | None = Field(
        description="{stress} when prestress stable, {dual, flexes} when not, null when undecided"
    )
    second_order_flex: SecondOrderFlex | None = Field(
        description="a witnessing second-order flex when not second-order rigid"
    )
    tolerances: TolerancesUsed

