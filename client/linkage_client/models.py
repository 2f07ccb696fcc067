"""Typed models of the service's answers (frozen dataclasses, numpy arrays for the numbers).

Why dataclasses and not pydantic: the client needs nothing but httpx and numpy, its fields hold
numpy arrays (which pydantic validates only as arbitrary types), and validation is the
service's job (the contract lets it add fields: unknown keys are ignored here, and every model
of an answer keeps the whole JSON on ``raw``). Field names are the answer's keys (``from`` is
``from_``); ``tests/client/test_models.py`` checks them against ``openapi/openapi.json``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Self

import numpy as np

from linkage_client._build import Model, build, generic
from linkage_client.labelled import Labelled

JSON = dict[str, Any]


def _raw() -> Any:
    return field(default_factory=dict, repr=False, compare=False)


# ---------------------------------------------------------------- the linkage (in and out)


@dataclass(frozen=True)
class Vertex(Model):
    id: str
    position: tuple[float, ...]
    fixed: bool | tuple[bool, ...] = False


@dataclass(frozen=True)
class Bar(Model):
    id: str
    ends: tuple[str, str]
    length: float | None = None


@dataclass(frozen=True)
class Linkage(Model):
    """A bar-and-joint linkage as the API takes and gives it (schema ``Linkage``).

    Examples
    --------
    >>> lk = Linkage.from_json({"vertices": [{"id": "P", "position": [0, 0], "fixed": True},
    ...                                      {"id": "A", "position": [3, 4]}],
    ...                         "bars": [{"id": "r", "ends": ["P", "A"]}]})
    >>> lk.lengths()
    {'r': 5.0}
    """

    vertices: tuple[Vertex, ...]
    bars: tuple[Bar, ...] = ()
    dimension: int = 2

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Self:
        lk = generic(cls, data)
        if "dimension" not in data and lk.vertices:
            lk = cls(lk.vertices, lk.bars, len(lk.vertices[0].position))
        return lk

    def to_json(self) -> JSON:
        """The request form (every field explicit, ``length`` only where given)."""
        vertices = [{"id": v.id, "position": [float(x) for x in v.position],
                     "fixed": v.fixed if isinstance(v.fixed, bool) else list(v.fixed)}
                    for v in self.vertices]
        bars: list[JSON] = []
        for b in self.bars:
            bar: JSON = {"id": b.id, "ends": list(b.ends)}
            if b.length is not None:
                bar["length"] = float(b.length)
            bars.append(bar)
        return {"dimension": self.dimension, "vertices": vertices, "bars": bars}

    @property
    def vertex_ids(self) -> tuple[str, ...]:
        return tuple(v.id for v in self.vertices)

    @property
    def bar_ids(self) -> tuple[str, ...]:
        return tuple(b.id for b in self.bars)

    @property
    def positions(self) -> Labelled:
        """``(V, d)`` positions, rows in vertex order."""
        return Labelled(self.vertex_ids,
                        np.array([v.position for v in self.vertices], dtype=np.float64)
                        .reshape(len(self.vertices), self.dimension))

    def fixed_axes(self) -> np.ndarray:
        """``(V, d)`` booleans: which axes of each vertex are pinned."""
        return np.array([[v.fixed] * self.dimension if isinstance(v.fixed, bool) else v.fixed
                         for v in self.vertices], dtype=bool).reshape(-1, self.dimension)

    def lengths(self) -> dict[str, float]:
        """Each bar's length: its given ``length``, else the distance of its ends."""
        pos = {v.id: np.asarray(v.position, dtype=np.float64) for v in self.vertices}
        return {b.id: float(b.length) if b.length is not None
                else float(np.linalg.norm(pos[b.ends[0]] - pos[b.ends[1]]))
                for b in self.bars}


def linkage_json(linkage: Linkage | Mapping[str, Any]) -> JSON:
    """A linkage given as a model or as JSON, in the request form."""
    return linkage.to_json() if isinstance(linkage, Linkage) else dict(linkage)


# ---------------------------------------------------------------- shared pieces


@dataclass(frozen=True)
class Health(Model):
    status: str
    version: str


@dataclass(frozen=True)
class PresetInfo(Model):
    name: str
    description: str
    parameters: dict[str, float]
    dimension: int | None = None


@dataclass(frozen=True)
class TolerancesUsed(Model):
    rank_rtol: float
    residual_atol: float
    q_rtol: float


@dataclass(frozen=True)
class SearchReport(Model):
    complete: bool
    reason: str | None
    time_budget_s: float | None = None


@dataclass(frozen=True)
class TangentForm(Model):
    vector: Labelled
    orientation: int
    log10_magnitude: float | None


# ---------------------------------------------------------------- first and second order


@dataclass(frozen=True)
class RigidityResult(Model):
    """``POST /v1/analysis/rigidity``: vectors as ``(V, d)`` arrays, stresses as ``(E,)``."""

    projection_residual: float
    input_residual: float
    projection_distance: float
    configuration: Labelled
    rank: int
    n_free: int
    n_constraints: int
    expected_dof: int
    dof: int
    critical: bool
    singular_values: np.ndarray
    singular_values_complete: bool
    zero_modes: list[Labelled]
    trivial_motions: int
    self_stresses: list[Labelled]
    tangent_form: TangentForm | None
    method: str
    tolerances: TolerancesUsed
    raw: JSON = _raw()


@dataclass(frozen=True)
class StressCertificate(Model):
    stress: Labelled
    min_eigenvalue: float | None


@dataclass(frozen=True)
class DualCertificate(Model):
    dual: np.ndarray
    flexes: list[Labelled]
    dual_residual: float


@dataclass(frozen=True)
class SecondOrderFlex(Model):
    velocity: Labelled
    acceleration: Labelled


@dataclass(frozen=True)
class SecondOrderResult(Model):
    """``POST /v1/analysis/second-order``."""

    projection_residual: float
    input_residual: float
    projection_distance: float
    configuration: Labelled
    kind: str
    reason: str | None
    critical: bool
    self_stress: Labelled | None
    zero_modes: list[Labelled]
    q: np.ndarray | None
    q_eigenvalues: np.ndarray | None
    tangents: list[Labelled]
    tangent_coefficients: np.ndarray
    prestress_stable: bool | None
    second_order_rigid: bool | None
    stability_reason: str
    certificate: StressCertificate | DualCertificate | None
    second_order_flex: SecondOrderFlex | None
    tolerances: TolerancesUsed
    raw: JSON = _raw()


# ---------------------------------------------------------------- configuration spaces


@dataclass(frozen=True)
class CriticalPoint(Model):
    index: int
    configuration: Labelled
    kind: str
    reason: str | None
    self_stress: Labelled | None
    zero_modes: list[Labelled]
    q_eigenvalues: np.ndarray | None
    tangents: list[Labelled]
    residual: float
    stress_residual: float


@dataclass(frozen=True)
class NearMiss(Model):
    configuration: Labelled
    singular_gap: float
    distance: float
    length_gap: float
    critical_configuration: Labelled


@dataclass(frozen=True)
class CriticalPointsResult(Model):
    """``POST /v1/analysis/critical-points``."""

    projection_residual: float
    input_residual: float
    projection_distance: float
    configuration: Labelled
    critical_points: list[CriticalPoint]
    near_misses: list[NearMiss]
    degenerate: bool
    search: SearchReport
    tolerances: TolerancesUsed
    raw: JSON = _raw()


@dataclass(frozen=True)
class Component(Model):
    """One traced component: ``positions`` ``(n, V, d)`` and ``angles`` ``(n, R)`` arrays.

    Decoded alike from the compact (packed base64) and the default (per-vertex lists) answer.
    """

    closed: bool
    through_start: bool
    positions: Labelled
    angles: Labelled
    winding: dict[str, int | None]
    critical_points: list[int]

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Self:
        def points(value: Mapping[str, Any]) -> Labelled:
            if "base64" in value:
                return Labelled.from_packed(value)
            return Labelled.from_series(value)

        return cls(closed=data["closed"], through_start=data["through_start"],
                   positions=points(data["positions"]), angles=points(data["angles"]),
                   winding=dict(data["winding"]), critical_points=list(data["critical_points"]))


@dataclass(frozen=True)
class Segment(Model):
    from_: int = field(metadata={"json": "from"})
    to: int
    component: int
    from_ray: int
    to_ray: int


@dataclass(frozen=True)
class SpaceResult(Model):
    """``POST /v1/analysis/configuration-space``."""

    projection_residual: float
    input_residual: float
    projection_distance: float
    configuration: Labelled
    components: list[Component]
    critical_points: list[CriticalPoint]
    segments: list[Segment]
    degenerate: bool
    search: SearchReport
    tolerances: TolerancesUsed
    raw: JSON = _raw()


@dataclass(frozen=True)
class BranchSplit(Model):
    index: int
    configuration: Labelled
    delta: float
    delta_linear: float
    shift: np.ndarray
    sign: int
    connects: list[list[int]]


@dataclass(frozen=True)
class SplittingResult(Model):
    """``POST /v1/analysis/splitting``."""

    branch_points: list[BranchSplit]
    critical_points_found: int
    search: SearchReport
    tolerances: TolerancesUsed
    raw: JSON = _raw()


@dataclass(frozen=True)
class RobustnessSearch(Model):
    complete: bool
    reason: str | None
    time_budget_s: float | None = None
    starts_planned: int | None = None
    starts_run: int | None = None
    critical_points_complete: bool | None = None
    planes: int | None = None


@dataclass(frozen=True)
class RobustnessResult(Model):
    """``POST /v1/analysis/robustness``."""

    margin: float | None
    nearest: dict[str, float]
    critical_configuration: Labelled
    starts: int
    converged: int
    success: bool
    message: str
    method: str
    guarantee: str
    search: RobustnessSearch
    tolerances: TolerancesUsed
    raw: JSON = _raw()


@dataclass(frozen=True)
class Region(Model):
    point: np.ndarray
    components: int | None
    signature: str
    cells: int


@dataclass(frozen=True)
class SliceSearch(Model):
    complete: bool
    reason: str | None
    regions_explored: int
    curves: int
    resolution: int
    time_budget_s: float | None = None


@dataclass(frozen=True)
class CriticalValuesResult(Model):
    """``POST /v1/analysis/critical-values``: each curve a ``(n, 2)`` array."""

    curves: list[np.ndarray]
    regions: list[Region]
    search: SliceSearch
    tolerances: TolerancesUsed
    raw: JSON = _raw()


@dataclass(frozen=True)
class Predicted(Model):
    branch_point: int
    sign: int
    delta: float
    connects: list[list[int]]
    traced_connects: list[list[int]] | None


@dataclass(frozen=True)
class Conflict(Model):
    branch_points: list[int]
    reason: str


@dataclass(frozen=True)
class DesignResult(Model):
    """``POST /v1/design/splitting``."""

    feasible: bool
    perturbation: dict[str, float]
    largest_change: float
    predicted: list[Predicted]
    conflicts: list[Conflict]
    verified: bool | None
    search: SearchReport
    tolerances: TolerancesUsed
    raw: JSON = _raw()


# ---------------------------------------------------------------- jobs and sweeps


@dataclass(frozen=True)
class Progress(Model):
    fraction: float
    message: str


@dataclass(frozen=True)
class JobError(Model):
    title: str
    detail: str
    loc: list[str | int] = field(default_factory=list)


#: Statuses after which a job no longer changes.
FINISHED = ("done", "failed", "cancelled")


@dataclass(frozen=True)
class Job(Model):
    """A job or sweep (``/v1/jobs/{id}``); ``result`` is the raw JSON when done."""

    id: str
    operation: str
    status: str
    progress: Progress
    created: float
    started: float | None = None
    finished: float | None = None
    expires: float | None = None
    result: Any | None = None
    error: JobError | None = None

    @property
    def location(self) -> str:
        return f"/v1/jobs/{self.id}"

    @property
    def done(self) -> bool:
        """True once the job can no longer change (done, failed or cancelled)."""
        return self.status in FINISHED


@dataclass(frozen=True)
class Operation(Model):
    operation: str
    request: str


@dataclass(frozen=True)
class SweepRow(Model):
    lengths: dict[str, float]
    components: int | None = None
    complete: bool | None = None
    critical_points: int | None = None
    margin: float | None = None
    windings: list[str] | None = None
    gated: bool | None = None
    error: str | None = None


@dataclass(frozen=True)
class SweepSummary(Model):
    points: int
    topologies: dict[str, int]
    gated: int | None
    fraction_gated: float | None
    smallest_margin: float | None
    smallest_margin_at: dict[str, float] | None
    critical: int | None
    incomplete: int
    errors: int


@dataclass(frozen=True)
class SweepResult(Model):
    """A sweep's result: one row per grid cell or sample, and their summary."""

    rows: list[SweepRow]
    summary: SweepSummary
    raw: JSON = _raw()

    def column(self, name: str) -> np.ndarray:
        """One swept length (or ``components``, ``margin``, ...) of every row as an array
        (``nan`` where a row has none)."""
        values = [r.lengths.get(name) if name in r.lengths else getattr(r, name, None)
                  for r in self.rows]
        return np.array([np.nan if v is None else v for v in values], dtype=np.float64)


#: The model of each job operation's result (``None``: the raw JSON).
RESULTS: dict[str, type[Model]] = {
    "analysis/rigidity": RigidityResult,
    "analysis/second-order": SecondOrderResult,
    "analysis/critical-points": CriticalPointsResult,
    "analysis/configuration-space": SpaceResult,
    "analysis/splitting": SplittingResult,
    "analysis/robustness": RobustnessResult,
    "analysis/critical-values": CriticalValuesResult,
    "design/splitting": DesignResult,
    "sweeps": SweepResult,
}


def result_of(operation: str, data: Any) -> Any:
    """A job's result as the model of its operation (the raw JSON for an unknown one)."""
    model = RESULTS.get(operation)
    return build(model, data) if model is not None and isinstance(data, Mapping) else data


def sequence(data: Any) -> Sequence[Any]:
    if not isinstance(data, list):
        raise TypeError(f"expected a JSON array, got {type(data).__name__}")
    return data
