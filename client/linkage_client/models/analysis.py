"""The answers of the analysis and design operations."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Self

import numpy as np

from linkage_client._build import Model
from linkage_client.labelled import Labelled
from linkage_client.models.linkage import (
    ProvedSoFar,
    SearchReport,
    TangentForm,
    TolerancesUsed,
)

JSON = dict[str, Any]


def _raw() -> Any:
    return field(default_factory=dict, repr=False, compare=False)


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
        return cls(closed=data["closed"], through_start=data["through_start"],
                   positions=_points(data["positions"]), angles=_points(data["angles"]),
                   winding=dict(data["winding"]), critical_points=list(data["critical_points"]))


@dataclass(frozen=True)
class Segment(Model):
    from_: int = field(metadata={"json": "from"})
    to: int
    component: int
    from_ray: int
    to_ray: int


def _points(value: Mapping[str, Any]) -> Labelled:
    """Points along a walk or at mesh vertices: ids on axis 1, from the compact (PackedArray)
    or the default (per-id lists) form alike."""
    if "base64" in value:
        return Labelled.from_packed(value)
    return Labelled.from_series(value)


@dataclass(frozen=True)
class HeightCritical(Model):
    """A critical point of the generic height of the Morse check (two degrees of freedom):
    ``index`` 0 minimum, 1 saddle, 2 maximum, -1 degenerate; ``surface`` -1 for none."""

    configuration: Labelled
    index: int
    surface: int


@dataclass(frozen=True)
class Surface(Model):
    """One compact component of a two-degree-of-freedom configuration space, triangulated:
    ``positions`` a ``(mesh vertices, V, d)`` array, ``triangles`` an ``(F, 3)`` int array.

    Decoded alike from the compact (packed base64) and the default (per-vertex lists) answer.
    """

    closed: bool
    positions: Labelled
    triangles: np.ndarray
    euler: int | None
    orientable: bool | None
    betti_z2: list[int] | None
    betti_q: list[int] | None
    genus: int | None
    defects: dict[str, int]
    inverted_triangles: int
    tangent_angle_max: float
    morse_sum: int | None
    morse_agrees: bool
    critical_points: list[int]
    apexes: list[int] = field(default_factory=list)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Self:
        def optional_list(key: str) -> list[int] | None:
            value = data.get(key)
            return None if value is None else list(value)

        triangles = np.asarray(data["triangles"], dtype=np.int64).reshape(-1, 3)
        return cls(closed=data["closed"], positions=_points(data["positions"]),
                   triangles=triangles, euler=data.get("euler"),
                   orientable=data.get("orientable"), betti_z2=optional_list("betti_z2"),
                   betti_q=optional_list("betti_q"), genus=data.get("genus"),
                   defects=dict(data["defects"]), inverted_triangles=data["inverted_triangles"],
                   tangent_angle_max=data["tangent_angle_max"], morse_sum=data.get("morse_sum"),
                   morse_agrees=data["morse_agrees"],
                   critical_points=list(data["critical_points"]),
                   apexes=list(data.get("apexes", [])))


@dataclass(frozen=True)
class SpaceResult(Model):
    """``POST /v1/analysis/configuration-space``: ``surfaces`` and ``height_critical_points``
    for two degrees of freedom (None for one)."""

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
    surfaces: list[Surface] | None = None
    height_critical_points: list[HeightCritical] | None = None
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
    delta_error: float | None = None
    resolved: bool | None = None


@dataclass(frozen=True)
class ConeSplit(Model):
    """A cone of a two-degree-of-freedom space and how a perturbation resolves it."""

    configuration: Labelled
    q_eigenvalues: np.ndarray
    delta: float
    delta_error: float
    sign: int
    sheets: int
    euler_change: int


@dataclass(frozen=True)
class SurfaceSplit(Model):
    """``splitting`` for two degrees of freedom: the cones, the predicted change of the Euler
    characteristic and its check by re-meshing (``euler``, ``betti_q`` at ``L + dL``,
    ``L - dL``)."""

    cones: list[ConeSplit]
    predicted_euler_difference: int | None
    euler: list[int | None]
    betti_q: list[list[int] | None]
    verified: bool
    message: str
    critical_betti_q: list[int] | None = None
    predicted_betti_q: list[list[int] | None] = field(default_factory=lambda: [None, None])


@dataclass(frozen=True)
class SplittingResult(Model):
    """``POST /v1/analysis/splitting``."""

    branch_points: list[BranchSplit]
    critical_points_found: int
    search: SearchReport
    tolerances: TolerancesUsed
    surface: SurfaceSplit | None = None
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
    argument: str | None = None
    argument_detail: str | None = None


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
    guarantee_detail: str | None = None
    exact_margin: float | None = None
    raw: JSON = _raw()


@dataclass(frozen=True)
class CellSigns(Model):
    """The paper's tau signs of one four-bar cell (``gate``: the gated chain's gate)."""

    cell: str
    bars: list[str]
    sides: list[float]
    signs: list[int]


@dataclass(frozen=True)
class Region(Model):
    """A map's region: its count (exact where ``components_exact``, else a lower bound), the
    tau signs of its four-bar cells, ``gated`` for chains with a gate, the winding patterns."""

    point: np.ndarray
    components: int | str | None
    signature: str
    cells: int
    argument: str | None = None
    components_exact: bool | None = None
    components_traced: int | None = None
    components_rule: str | None = None
    tau_signs: list[CellSigns] | None = None
    gated: bool | None = None
    gated_reason: str | None = None
    windings: list[str] | None = None


@dataclass(frozen=True)
class SliceSearch(Model):
    complete: bool
    reason: str | None
    regions_explored: int
    curves: int
    resolution: int
    time_budget_s: float | None = None
    argument: str | None = None
    argument_detail: str | None = None
    proved: ProvedSoFar | None = None


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
    delta_error: float | None = None


@dataclass(frozen=True)
class Conflict(Model):
    branch_points: list[int]
    reason: str


@dataclass(frozen=True)
class SurfaceDesign(Model):
    """``design`` for two degrees of freedom: every cone at ``L + dL``, the sign each target
    asked for, the predicted change of the Euler characteristic and the re-meshed topology
    (``euler``, ``betti_q`` at ``L + dL``, ``L - dL``)."""

    cones: list[ConeSplit]
    asked: list[int]
    targets_met: bool | None
    euler_change: int | None
    predicted_euler_difference: int | None
    euler: list[int | None]
    betti_q: list[list[int] | None]
    remeshed_complete: bool
    message: str
    critical_betti_q: list[int] | None = None
    predicted_betti_q: list[list[int] | None] = field(default_factory=lambda: [None, None])


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
    surface: SurfaceDesign | None = None
    raw: JSON = _raw()


