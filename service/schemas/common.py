"""Models shared by every endpoint: linkages, tolerances, problems."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StrictBool,
    ValidationError,
    ValidatorFunctionWrapHandler,
    WrapValidator,
)
from pydantic_core import PydanticCustomError

Finite = Annotated[float, Field(strict=True, allow_inf_nan=False)]
Positive = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0)]
Ident = Annotated[str, Field(min_length=1, max_length=100)]
# Hard caps that keep parsing bounded; the configured limits (settings) are checked by the engine.
MAX_ITEMS = 1_000_000

VertexVectors = dict[str, list[float]]
"""Per-vertex vectors ``{vertex_id: [x, y(, z)]}``."""
BarValues = dict[str, float]
"""Per-bar values ``{bar_id: value}``."""


def _one_fixed_error(value: Any, handler: ValidatorFunctionWrapHandler) -> Any:
    """Report a bad ``fixed`` once, at the field, instead of once per union member."""
    try:
        return handler(value)
    except ValidationError:
        raise PydanticCustomError(
            "fixed_type", "must be a boolean or a list of booleans, one per axis"
        ) from None


Fixed = Annotated[StrictBool | list[StrictBool], WrapValidator(_one_fixed_error)]


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Vertex(Strict):
    id: Ident
    position: list[Finite] = Field(min_length=1, max_length=3, description="[x, y] or [x, y, z]")
    fixed: Fixed = Field(
        False,
        description="false (free), true (pinned) or one boolean per axis (a slider that moves "
        "only along its free axes)",
    )


class Bar(Strict):
    id: Ident
    ends: list[Ident] = Field(min_length=2, max_length=2, description="two vertex ids")
    length: Positive | None = Field(
        None, description="target length; default: the distance between the ends as given"
    )


class Linkage(Strict):
    dimension: Literal[2, 3] = 2
    vertices: list[Vertex] = Field(min_length=1, max_length=MAX_ITEMS)
    bars: list[Bar] = Field(default_factory=list, max_length=MAX_ITEMS)

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "example": {
                "dimension": 2,
                "vertices": [
                    {"id": "P1", "position": [0.0, 0.0], "fixed": True},
                    {"id": "P2", "position": [1.0, 0.0], "fixed": True},
                    {"id": "A", "position": [0.5, 0.8660254037844386]},
                    {"id": "B", "position": [1.5, 0.8660254037844386]},
                ],
                "bars": [
                    {"id": "L1", "ends": ["P1", "A"], "length": 1.0},
                    {"id": "L2", "ends": ["A", "B"], "length": 1.0},
                    {"id": "L3", "ends": ["P2", "B"], "length": 1.0},
                ],
            }
        },
    )


# Relative thresholds below a few machine epsilons decide nothing (engine.tolerances).
_RelTol = Annotated[float, Field(strict=True, ge=1e-14, lt=1, allow_inf_nan=False)]
_AbsTol = Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)]


class Tolerances(Strict):
    rank_rtol: _RelTol | None = Field(
        None, description="singular values <= rank_rtol * s_max count as zero (default 1e-8)"
    )
    residual_atol: _AbsTol | None = Field(
        None, description="largest allowed bar-length error of a configuration (default 1e-9 "
        "times the median bar length)"
    )
    q_rtol: _RelTol | None = Field(
        None, description="eigenvalues of Q below q_rtol * ||H_sigma|| count as zero (default 1e-6)"
    )


class TolerancesUsed(BaseModel):
    rank_rtol: float
    residual_atol: float
    q_rtol: float


class AnalysisRequest(Strict):
    linkage: Linkage
    tolerances: Tolerances | None = None


class ProblemItem(BaseModel):
    loc: list[str | int]
    msg: str


class Problem(BaseModel):
    """RFC 9457 problem details."""

    type: str
    title: str
    status: int
    detail: str
    errors: list[ProblemItem] = Field(default_factory=list)
