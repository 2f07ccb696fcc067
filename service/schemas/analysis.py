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
    tolerances: TolerancesUsed
