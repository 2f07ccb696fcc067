"""Models shared by every endpoint: linkages, tolerances, problems."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ModelWrapValidatorHandler,
    StrictBool,
    ValidationError,
    ValidatorFunctionWrapHandler,
    WrapValidator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from service.gcpause import gc_paused

Finite = Annotated[float, Field(strict=True, allow_inf_nan=False)]
Positive = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0)]
# Ids appear in answers, logs and figures: printable characters only. Excluded: the C0 and C1
# control characters and DEL, and the invisible format characters that can reorder or hide
# text (soft hyphen, zero-width spaces and joiners, bidirectional marks, embeddings and
# overrides, line and paragraph separators, word joiners and invisible operators, BOM). The
# pattern uses escapes that Python, Rust (pydantic-core) and ECMAScript regexes all read.
IDENT_PATTERN = (r"^[^\x00-\x1f\x7f-\x9f\u00ad\u200b-\u200f\u2028-\u202e\u2060-\u206f"
                 r"\ufeff]+$")
Ident = Annotated[str, Field(
    min_length=1, max_length=100, pattern=IDENT_PATTERN,
    description="1 to 100 printable characters: no control characters (U+0000-U+001F, "
    "U+007F-U+009F) and no invisible format characters (U+00AD, U+200B-U+200F, "
    "U+2028-U+202E, U+2060-U+206F, U+FEFF)")]
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


def _restore(cls: type[BaseModel], values: dict[str, Any], fields_set: set[str]) -> Any:
    """A model from values that were validated before it was pickled (no validation)."""
    obj = cls.__new__(cls)
    object.__setattr__(obj, "__dict__", values)
    object.__setattr__(obj, "__pydantic_fields_set__", fields_set)
    object.__setattr__(obj, "__pydantic_extra__", None)
    object.__setattr__(obj, "__pydantic_private__", None)
    return obj


def _restore_linkage(
    state: dict[str, Any],
    fields_set: set[str],
    vertices: tuple[list[str], list[list[float]], list[Any], list[bool]],
    bars: tuple[list[str], list[list[str]], list[float | None], list[bool]],
) -> Linkage:
    """Inverse of :meth:`Linkage.__reduce__`."""
    v_set, v_fixed_set = {"id", "position"}, {"id", "position", "fixed"}
    b_set, b_length_set = {"id", "ends"}, {"id", "ends", "length"}
    with gc_paused():
        state["vertices"] = [
            _restore(Vertex, {"id": i, "position": p, "fixed": f},
                     set(v_fixed_set if s else v_set))
            for i, p, f, s in zip(*vertices, strict=True)
        ]
        state["bars"] = [
            _restore(Bar, {"id": i, "ends": e, "length": ln}, set(b_length_set if s else b_set))
            for i, e, ln, s in zip(*bars, strict=True)
        ]
    return _restore(Linkage, state, fields_set)


class Linkage(Strict):
    dimension: Literal[2, 3] = 2
    vertices: list[Vertex] = Field(min_length=1, max_length=MAX_ITEMS)
    bars: list[Bar] = Field(default_factory=list, max_length=MAX_ITEMS)

    @model_validator(mode="wrap")
    @classmethod
    def _validate_in_bulk(cls, data: Any, handler: ModelWrapValidatorHandler[Linkage]) -> Linkage:
        # A large linkage is some 10^5 small objects: see service.gcpause.
        with gc_paused():
            return handler(data)

    def __reduce__(self) -> tuple[Any, ...]:
        # Requests travel to the engine's worker processes by pickle. Pickled model by model,
        # a 10,000-rotor chain (40,000 models) takes about 0.7 s to pickle and unpickle; as
        # columns of plain values it takes a fraction of that. Both ends hold validated models.
        vs, bs = self.vertices, self.bars
        vertices = ([v.id for v in vs], [v.position for v in vs], [v.fixed for v in vs],
                    ["fixed" in v.__pydantic_fields_set__ for v in vs])
        bars = ([b.id for b in bs], [b.ends for b in bs], [b.length for b in bs],
                ["length" in b.__pydantic_fields_set__ for b in bs])
        state = {k: v for k, v in self.__dict__.items() if k not in ("vertices", "bars")}
        return (_restore_linkage, (state, set(self.__pydantic_fields_set__), vertices, bars))

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
