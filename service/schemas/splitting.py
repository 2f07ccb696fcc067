"""Requests and responses of ``/v1/analysis/splitting`` (and its figure)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.common import (
    EXAMPLE_LINKAGE,
    EXAMPLE_TOLERANCES,
    Finite,
    Ident,
    Linkage,
    SearchReport,
    Strict,
    Tolerances,
    TolerancesUsed,
    VertexVectors,
    examples,
)
from service.schemas.space import SpaceOptions


class SplittingRequest(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"linkage": EXAMPLE_LINKAGE, "perturbation": {"L2": 0.01},
         "tolerances": EXAMPLE_TOLERANCES}))

    linkage: Linkage
    perturbation: dict[Ident, Finite] = Field(description="{bar_id: dL}")
    tolerances: Tolerances | None = None
    options: SpaceOptions | None = None


class BranchSplitOut(BaseModel):
    index: int
    configuration: VertexVectors
    delta: float = Field(description="Delta of the conic (c - dc)^T Q (c - dc) = Delta")
    delta_linear: float = Field(description="first-order Delta = 4 sum sigma_a L_a dL_a")
    shift: list[float] = Field(description="dc, the centre shift on the zero modes")
    delta_error: float = Field(
        description="the scale of delta's own error (the self-stress's error, the critical "
        "point's residual, rounding, and the term the second-order model leaves out)"
    )
    resolved: bool = Field(description="|delta| > delta_error: the sign is decided")
    sign: int = Field(description="sign of delta: 1 or -1 where resolved, 0 (undecided: "
                      "|delta| <= delta_error) otherwise")
    connects: list[list[int]] = Field(description="joined ray pairs (empty where sign is 0)")


class ConeSplitOut(BaseModel):
    configuration: VertexVectors
    q_eigenvalues: list[float] = Field(description="Q on the three zero modes (indefinite: "
                                       "a cone)")
    delta: float = Field(description="Delta of the quadric (c - dc)^T Q (c - dc) = Delta")
    delta_error: float
    sign: int = Field(description="sign of delta; 0: undecided (|delta| <= delta_error)")
    sheets: int = Field(description="the perturbed cone is a hyperboloid of 1 sheet (the two "
                        "nappes joined by a neck) or 2 (parted); 0 where undecided")
    euler_change: int = Field(description="change of the Euler characteristic at this cone "
                              "from the unperturbed space: 2 sheets - 3")


class SurfaceSplitOut(BaseModel):
    """Two degrees of freedom: every cone, how it resolves, and the re-meshed check."""

    cones: list[ConeSplitOut]
    predicted_euler_difference: int | None = Field(
        description="chi(L + dL) - chi(L - dL) = 2 sum euler_change (null: a cone undecided)")
    euler: list[int | None] = Field(description="re-meshed Euler characteristics at L + dL "
                                    "and L - dL (summed over the surfaces)")
    betti_q: list[list[int] | None] = Field(description="re-meshed b0, b1, b2 over Q at "
                                            "L + dL and L - dL (summed over the surfaces)")
    verified: bool = Field(description="the re-meshed difference equals the prediction")
    critical_betti_q: list[int] | None = Field(
        description="b0, b1, b2 over Q of the critical space at L, meshed through its "
        "cones (null: its mesh incomplete)")
    predicted_betti_q: list[list[int] | None] = Field(
        description="b0, b1, b2 over Q predicted at "
        "L + dL and L - dL: the critical space's mesh with each apex resolved as its cone "
        "resolves (two sheets: the apex split; one: a tube between its link's two cycles)")
    message: str


class SplittingResponse(BaseModel):
    surface: SurfaceSplitOut | None = Field(
        None, description="two degrees of freedom (M - E = 2): the cones' resolution; "
        "branch_points is then empty")
    branch_points: list[BranchSplitOut]
    critical_points_found: int
    search: SearchReport = Field(
        description="the critical-point search behind the answer (as in critical-points): "
        "complete, reason, time_budget_s"
    )
    tolerances: TolerancesUsed
