"""Requests and responses of ``/v1/analysis/critical-points`` and
``/v1/analysis/configuration-space``, and the search options every search takes."""

from __future__ import annotations

from typing import Annotated, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.analysis import Projection
from service.schemas.common import (
    EXAMPLE_LINKAGE,
    EXAMPLE_TOLERANCES,
    BarValues,
    Linkage,
    SearchReport,
    Strict,
    Tolerances,
    TolerancesUsed,
    VertexVectors,
    default_of,
    examples,
)

_StrainTol = Annotated[float, Field(strict=True, gt=0, le=0.2, allow_inf_nan=False)]


TimeBudget = Annotated[float, Field(strict=True, gt=0, le=86_400, allow_inf_nan=False)]
TIME_BUDGET_DOC = (
    "seconds the search may take before it answers with what it found, marked "
    "search.complete = false with search.reason = \"time\" (default LINKAGE_SEARCH_TIME_S, 4 s; "
    "at most three quarters of LINKAGE_TIME_LIMIT_S: a larger value is lowered to that, and "
    "search.time_budget_s says what was used). Jobs use the job's time limit instead."
)


class SpaceOptions(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"max_points": 20000, "strain_tol": 0.01, "step_max": 0.1, "angles": 60,
         "random_starts": 12, "max_components": 32, "seed": 0, "time_budget_s": 4.0,
         "points": "objects"}))

    max_points: Annotated[int, Field(strict=True, ge=10, le=200_000)] | None = Field(
        None, description="budget of points per traced curve (default 20000)",
        json_schema_extra=default_of(20000),
    )
    strain_tol: _StrainTol | None = Field(
        None, description="largest relative bar strain of a predictor step (default 0.01)",
        json_schema_extra=default_of(0.01),
    )
    step_max: Annotated[float, Field(strict=True, gt=0, allow_inf_nan=False)] | None = Field(
        None, description="largest distance between consecutive points (default: a tenth of "
        "the median bar length)"
    )
    angles: Annotated[int, Field(strict=True, ge=4, le=2000)] | None = Field(
        None, description="rotor angles swept for seeds (default 60)",
        json_schema_extra=default_of(60),
    )
    random_starts: Annotated[int, Field(strict=True, ge=0, le=1000)] | None = Field(
        None, description="random starts for seeds and for the critical-point search (default 12)",
        json_schema_extra=default_of(12),
    )
    max_components: Annotated[int, Field(strict=True, ge=1, le=1000)] | None = Field(
        None, description="budget of traced components (default 32)",
        json_schema_extra=default_of(32),
    )
    seed: Annotated[int, Field(strict=True, ge=0, le=2**32 - 1)] | None = Field(
        None, description="seed of the random starts (default 0)",
        json_schema_extra=default_of(0),
    )
    homotopy_paths_max: Annotated[int, Field(strict=True, ge=0, le=8192)] | None = Field(
        None, description="largest path count of the homotopy that proves a search complete "
        "(the witness points, docs/methods.md; 2^r r paths for r quadrics: 24 for the "
        "four-bar, 160 for the three-rotor, 896 for a 3D chain of four hinged rotors; "
        "default 512, about a second); 0 skips it",
        json_schema_extra=default_of(512),
    )
    surface_step: Annotated[float, Field(strict=True, ge=0.02, le=2.0,
                                         allow_inf_nan=False)] | None = Field(
        None, description="edge length of the triangles of a two-degree-of-freedom "
        "configuration space (M - E = 2: the answer's surfaces), relative to the median bar "
        "length (default 0.25); the other searches ignore it",
        json_schema_extra=default_of(0.25),
    )
    max_triangles: Annotated[int, Field(strict=True, ge=100, le=200_000)] | None = Field(
        None, description="budget of triangles over every surface of a two-degree-of-freedom "
        "configuration space (default 20000); the other searches ignore it",
        json_schema_extra=default_of(20000),
    )
    time_budget_s: TimeBudget | None = Field(None, description=TIME_BUDGET_DOC)
    points: Literal["objects", "compact"] | None = Field(
        None, description="how configuration-space components carry their points: \"objects\" "
        "(default), per-vertex lists of [x, y]; \"compact\", each of positions and angles as "
        "one little-endian float64 array in base64 (PackedArray), much faster to send and to "
        "parse. Only /v1/analysis/configuration-space answers with points; the other searches "
        "ignore it",
        json_schema_extra=default_of("objects"),
    )


class SpaceRequest(Strict):
    model_config = ConfigDict(extra="forbid", json_schema_extra=examples(
        {"linkage": EXAMPLE_LINKAGE, "tolerances": EXAMPLE_TOLERANCES,
         "options": {"angles": 60, "seed": 0, "time_budget_s": 4.0}}))

    linkage: Linkage
    tolerances: Tolerances | None = None
    options: SpaceOptions | None = None


class CriticalPointOut(BaseModel):
    index: int
    configuration: VertexVectors
    kind: str = Field(description="branch, rigid or degenerate")
    reason: str | None
    self_stress: BarValues | None
    zero_modes: list[VertexVectors]
    q_eigenvalues: list[float] | None
    tangents: list[VertexVectors] = Field(description="rays +t0, -t0, +t1, -t1 are numbered 0..3")
    residual: float = Field(description="largest |l - L| at the critical configuration")
    stress_residual: float = Field(description="|J^T sigma| / |J|")


class NearMissOut(BaseModel):
    configuration: VertexVectors = Field(description="closest approach on the configuration space")
    singular_gap: float = Field(description="s_min / s_max of J there")
    distance: float = Field(description="configuration distance to the nearest critical "
                            "configuration (of nearby lengths)")
    length_gap: float = Field(description="largest length change that makes it critical")
    critical_configuration: VertexVectors


class CriticalPointsResponse(Projection):
    critical_points: list[CriticalPointOut]
    near_misses: list[NearMissOut]
    degenerate: bool = Field(description="a critical point is degenerate (e.g. non-isolated)")
    search: SearchReport
    tolerances: TolerancesUsed


class PackedArray(BaseModel):
    """An array of float64 packed for speed (``options.points = "compact"``): decode with
    ``numpy.frombuffer(base64.b64decode(base64_), "<f8").reshape(shape)``."""

    ids: list[str] = Field(description="what indexes the array's second axis: the vertex ids "
                           "(positions) or the rotor bar ids (angles), in order")
    shape: list[int] = Field(description="(points, vertices, d) for positions, (points, rotors) "
                             "for angles")
    dtype: Literal["<f8"] = Field(description="little-endian IEEE 754 float64, C order")
    base64: str = Field(description="the array's bytes in base64 (RFC 4648, with padding)")

    #: base64 needs no JSON escaping: service.serialise.dumps_parts copies it into the answer
    #: as it is (megabytes per component) instead of passing it through orjson.
    raw_json_fields: ClassVar[tuple[str, ...]] = ("base64",)


class ComponentOut(BaseModel):
    closed: bool
    through_start: bool
    positions: dict[str, list[list[float]]] | PackedArray = Field(
        description="per vertex, the walk along the component (closed ones repeat the first "
        "point at the end); with options.points = \"compact\" one PackedArray of shape "
        "(points, vertices, d)"
    )
    angles: dict[str, list[float]] | PackedArray = Field(
        description="unwrapped rotor angles along the walk; with options.points = \"compact\" "
        "one PackedArray of shape (points, rotors)"
    )
    winding: dict[str, int | None] = Field(description="net turns of each rotor (closed only)")
    critical_points: list[int]


class SegmentOut(BaseModel):
    from_: int = Field(alias="from", serialization_alias="from")
    to: int
    component: int
    from_ray: int
    to_ray: int

    model_config = {"populate_by_name": True}


class HeightCriticalOut(BaseModel):
    configuration: VertexVectors
    index: int = Field(description="Morse index of the height there: 0 minimum, 1 saddle, "
                       "2 maximum; -1 degenerate")
    surface: int = Field(description="the surface it lies on (-1: none of the meshed ones)")


class SurfaceOut(BaseModel):
    """One compact component of a two-degree-of-freedom configuration space, triangulated."""

    closed: bool = Field(description="the marching closed (no open front): a closed surface")
    positions: dict[str, list[list[float]]] | PackedArray = Field(
        description="per vertex of the linkage, its position at each mesh vertex; with "
        "options.points = \"compact\" one PackedArray of shape (mesh vertices, vertices, d)"
    )
    triangles: list[list[int]] = Field(description="mesh vertex indices, counter-clockwise "
                                       "in the positive tangent frames")
    euler: int | None = Field(description="Euler characteristic V - E + F of the mesh")
    orientable: bool | None
    betti_z2: list[int] | None = Field(description="b0, b1, b2 over Z/2")
    betti_q: list[int] | None = Field(description="b0, b1, b2 over Q")
    genus: int | None = Field(description="of a closed connected surface")
    defects: dict[str, int] = Field(description="open_edges, branched_edges, "
                                    "pinched_vertices, repeated_triangles: all 0 for a closed "
                                    "2-manifold")
    inverted_triangles: int = Field(description="triangles negative in two of their vertices' "
                                    "tangent frames (folded)")
    tangent_angle_max: float = Field(description="largest angle (degrees) between a mesh "
                                     "edge and the tangent planes at its ends")
    morse_sum: int | None = Field(description="sum of (-1)^index over the height's critical "
                                  "points on it (null: one is degenerate)")
    morse_agrees: bool = Field(description="morse_sum equals euler (the Morse check)")
    critical_points: list[int] = Field(description="the linkage's critical points on it")
    apexes: list[int] = Field(default_factory=list, description=(
        "mesh vertices at the cones (critical points with Q indefinite on three zero modes) "
        "the surface passes through: each apex's link is two cycles, one per nappe, so "
        "defects.pinched_vertices counts them and genus is null"))


class SpaceResponse(Projection):
    components: list[ComponentOut]
    critical_points: list[CriticalPointOut]
    segments: list[SegmentOut] = Field(
        description="at critical lengths: which critical points each branch joins"
    )
    degenerate: bool
    surfaces: list[SurfaceOut] | None = Field(
        None, description="two degrees of freedom (M - E = 2, something fixed): every compact "
        "component as a triangulated surface with its topology (components and segments are "
        "then empty); null for one degree of freedom")
    height_critical_points: list[HeightCriticalOut] | None = Field(
        None, description="two degrees of freedom: the critical points of the generic height "
        "of the Morse check, with their indices")
    search: SearchReport
    tolerances: TolerancesUsed
