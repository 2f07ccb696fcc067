"""Models shared by every endpoint: linkages, tolerances, problems."""

from __future__ import annotations

import math
from array import array
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
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

from engine.model.linkage import MAX_COORDINATE
from service.gcpause import gc_paused

Finite = Annotated[float, Field(strict=True, allow_inf_nan=False)]
Positive = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0)]
#: A vertex's coordinate: finite and at most ``MAX_COORDINATE`` in magnitude (the engine's bound,
#: beyond which squared lengths overflow).
Coordinate = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=-MAX_COORDINATE,
                                    le=MAX_COORDINATE)]
#: A bar's length: positive and at most the largest distance of two coordinates.
Length = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0,
                                le=2 * MAX_COORDINATE)]
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
    position: list[Coordinate] = Field(
        min_length=1, max_length=3,
        description="[x, y] or [x, y, z] (as many as the linkage's dimension), each at most "
        f"{MAX_COORDINATE:g} in magnitude")
    fixed: Fixed = Field(
        False,
        description="false (free), true (pinned) or one boolean per axis (a slider that moves "
        "only along its free axes)",
    )


def _distinct_ends(ends: list[str]) -> list[str]:
    if len(ends) == 2 and ends[0] == ends[1]:
        raise PydanticCustomError("ends_distinct", "a bar joins two different vertices")
    return ends


def _unique(values: list[str]) -> list[str]:
    if len(set(values)) != len(values):
        raise PydanticCustomError("unique_items", "the items must be different")
    return values


#: Bar ids that may not repeat (``uniqueItems``), as the engine requires where it says so.
UniqueIdents = Annotated[list[Ident], AfterValidator(_unique)]


class Bar(Strict):
    id: Ident
    ends: Annotated[list[Ident], AfterValidator(_distinct_ends)] = Field(
        min_length=2, max_length=2, json_schema_extra={"uniqueItems": True},
        description="two different vertex ids")
    length: Length | None = Field(
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


_SEP = "\x00"  # never inside an id (IDENT_PATTERN): joins ids into one string for pickling


def _pack_strings(items: list[str]) -> str | list[str]:
    """One string instead of many (pickled as one object), unless an item holds the separator
    (a model built without validation)."""
    joined = _SEP.join(items)
    return joined if joined.count(_SEP) == len(items) - 1 else items


def _unpack_strings(packed: str | list[str], n: int) -> list[str]:
    if isinstance(packed, list):
        return packed
    return packed.split(_SEP) if n else []


def _unpack_vectors(sizes: bytes, flat: array[float]) -> list[list[float]]:
    values = flat.tolist()
    if sizes and sizes.count(sizes[0]) == len(sizes):  # one dimension throughout: the usual case
        d = sizes[0]
        return [values[k:k + d] for k in range(0, len(values), d)]
    out, k = [], 0
    for size in sizes:
        out.append(values[k:k + size])
        k += size
    return out


def _restore_linkage(
    state: dict[str, Any],
    fields_set: set[str],
    vertices: tuple[int, str | list[str], bytes, array[float], list[Any], bytes],
    bars: tuple[int, str | list[str], str | list[str], array[float], bytes],
) -> Linkage:
    """Inverse of :meth:`Linkage.__reduce__`."""
    v_set, v_fixed_set = {"id", "position"}, {"id", "position", "fixed"}
    b_set, b_length_set = {"id", "ends"}, {"id", "ends", "length"}
    nv, v_ids, sizes, flat, fixed, v_given = vertices
    nb, b_ids, b_ends, lengths, b_given = bars
    with gc_paused():
        ends = _unpack_strings(b_ends, 2 * nb)
        state["vertices"] = [
            _restore(Vertex, {"id": i, "position": p, "fixed": f},
                     set(v_fixed_set if s else v_set))
            for i, p, f, s in zip(_unpack_strings(v_ids, nv), _unpack_vectors(sizes, flat),
                                  fixed, v_given, strict=True)
        ]
        state["bars"] = [
            _restore(Bar, {"id": i, "ends": [a, b], "length": None if ln != ln else ln},
                     set(b_length_set if s else b_set))  # ln != ln: NaN, no length given
            for i, a, b, ln, s in zip(_unpack_strings(b_ids, nb), ends[0::2], ends[1::2],
                                      lengths.tolist(), b_given, strict=True)
        ]
    return _restore(Linkage, state, fields_set)


#: The equilateral four-bar (the paper's, with three branch points) at theta = 60 degrees: the
#: linkage of every request example in the OpenAPI schema (tests/service/test_examples.py posts
#: each one and expects 2xx).
EXAMPLE_LINKAGE: dict[str, Any] = {
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
#: The tolerances of the request examples: the engine's defaults for bars of length 1.
EXAMPLE_TOLERANCES: dict[str, float] = {"rank_rtol": 1e-8, "residual_atol": 1e-9, "q_rtol": 1e-6}


def examples(*bodies: dict[str, Any]) -> dict[str, Any]:
    """``json_schema_extra`` of a request model: complete, valid requests that ``/docs``
    pre-fills (without them Swagger UI builds one from the fields' bounds, e.g. a
    ``residual_atol`` of 1, which is refused)."""
    return {"examples": list(bodies)}


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
        # Requests travel to and from the engine's worker processes by pickle. Pickled model by
        # model, a 10,000-rotor chain (40,000 models) takes about 0.7 s to pickle and unpickle;
        # even as columns of plain values, pickling is one C call that holds the GIL for tens
        # of milliseconds per 10^4 vertices (the event loop waits). So the columns are packed:
        # ids joined into one string, coordinates and lengths in one float array each. Both
        # ends hold validated models.
        vs, bs = self.vertices, self.bars
        positions = [v.position for v in vs]
        vertices = (
            len(vs), _pack_strings([v.id for v in vs]), bytes(len(p) for p in positions),
            array("d", [x for p in positions for x in p]), [v.fixed for v in vs],
            bytes("fixed" in v.__pydantic_fields_set__ for v in vs),
        )
        bars = (
            len(bs), _pack_strings([b.id for b in bs]),
            _pack_strings([end for b in bs for end in b.ends]),
            array("d", [math.nan if b.length is None else b.length for b in bs]),
            bytes("length" in b.__pydantic_fields_set__ for b in bs),
        )
        state = {k: v for k, v in self.__dict__.items() if k not in ("vertices", "bars")}
        return (_restore_linkage, (state, set(self.__pydantic_fields_set__), vertices, bars))

    model_config = ConfigDict(extra="forbid", json_schema_extra={"example": EXAMPLE_LINKAGE})


def default_of(value: float | str) -> dict[str, Any]:
    """``json_schema_extra`` of an optional field whose omission (or null) means the engine's
    default ``value``: the OpenAPI schema shows that default machine-readably while the field
    stays ``None`` here, so the engine's own default is the one applied (a test checks that
    the two agree)."""
    return {"default": value}


# Relative thresholds below a few machine epsilons decide nothing (engine.model.tolerances).
_RelTol = Annotated[float, Field(strict=True, ge=1e-14, lt=1, allow_inf_nan=False)]
_AbsTol = Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)]


class Tolerances(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(EXAMPLE_TOLERANCES))

    rank_rtol: _RelTol | None = Field(
        None, description="singular values <= rank_rtol * s_max count as zero (default 1e-8)",
        json_schema_extra=default_of(1e-8),
    )
    residual_atol: _AbsTol | None = Field(
        None, description="largest allowed bar-length error of a configuration (default 1e-9 "
        "times the median bar length)"
    )
    q_rtol: _RelTol | None = Field(
        None,
        description="eigenvalues of Q below q_rtol * ||H_sigma|| count as zero (default 1e-6)",
        json_schema_extra=default_of(1e-6),
    )


class TolerancesUsed(BaseModel):
    rank_rtol: float
    residual_atol: float
    q_rtol: float


class AnalysisRequest(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"linkage": EXAMPLE_LINKAGE,
         "tolerances": EXAMPLE_TOLERANCES}))

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


#: Why a search is incomplete (``search.reason``).
SearchReason = Literal["time", "budget", "degenerate", "unresolved", "searched"]


class CountClaim(BaseModel):
    """How many of a kind an answer found, and whether that is all of them."""

    count: int | str = Field(
        description="how many (a decimal string beyond 2^53 - 1, e.g. a long chain's "
        "components counted by the chain rules)"
    )
    exact: bool = Field(
        description="true: exactly this many (the answer is complete, or an argument covers "
        "this part alone); false: at least this many (what was found)"
    )


class ProvedSoFar(BaseModel):
    """What an answer proves, also when it is incomplete (``search.proved``)."""

    critical_points: CountClaim | None = Field(
        None, description="the critical points: exact when the answer is complete, or when the "
        "homotopy (every singular solution refined to a critical point of the answer) or the "
        "chain rules (none) prove them all while another part of the search was cut short"
    )
    components: CountClaim | None = Field(
        None, description="the components (configuration-space answers only): exact when the "
        "answer is complete or the chain rules count them (``components_total``), else the "
        "number traced, a lower bound"
    )


class SearchReport(BaseModel):
    """What a search did and whether its answer is complete (``engine.model.report.SearchReport``).
    ``complete`` and ``reason`` are always there; the method's own counts (``method``,
    ``seeds``, ``curves_traced``, ``open_curves``, ``critical_candidates``,
    ``components_total``, ``closed_form_*``, ...) are further properties; a count beyond
    2^53 - 1 (the largest integer a JSON number holds exactly; a Kane-Lubensky chain of n >= 55
    spinners has 2^(n-1) components) is a decimal string."""

    model_config = ConfigDict(extra="allow")

    complete: bool = Field(
        description="nothing was cut short and an argument (``argument``) proves that nothing "
        "was missed"
    )
    reason: SearchReason | None = Field(
        description="why it is incomplete: time (the deadline stopped it), budget (a count ran "
        "out: components, assemblies, points of a curve), degenerate (a critical point that "
        "is not isolated), unresolved (a curve or segment stopped open for a numerical "
        "reason), searched (nothing was cut short, but no argument proves that the seeds and "
        "random starts found everything: what was searched is in the other fields); null when "
        "complete"
    )
    argument: Literal["derived", "proved"] | None = Field(
        None, description="what proves the answer complete: derived (a closed form, the chain "
        "rules of rotor chains, a certified decomposition) or proved (every real solution of "
        "a polynomial system whose solutions include a point on every component and every "
        "critical point, found by homotopy continuation: see docs/methods.md); null without "
        "an argument"
    )
    argument_detail: str | None = Field(
        None, description="the argument in a sentence, with its counts (or why it failed)"
    )
    time_budget_s: float | None = Field(
        None, description="seconds the search was given (options.time_budget_s or "
        "LINKAGE_SEARCH_TIME_S; a job's own time limit)"
    )
    proved: ProvedSoFar | None = Field(
        None, description="what the answer proves so far, also when incomplete: the critical "
        "points and components found, each exact or a lower bound (configuration-space and "
        "critical-point searches)"
    )
