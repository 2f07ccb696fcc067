"""What a search of the configuration space answers, and its options.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from engine.local.critical import CriticalPoint, NearMiss
from engine.model.constraints import Constraints
from engine.model.errors import InvalidLinkage
from engine.model.linkage import Linkage
from engine.model.report import SearchReport
from engine.space.trace import (
    TraceOptions,
)
from engine.space.witnesses import PATHS_MAX

#: Smallest ``step_max`` accepted, relative to the median bar length.
MIN_STEP_MAX_REL = 1e-6


@dataclass(frozen=True)
class SpaceOptions:
    """Controls of the exploration (every cost is bounded by these)."""

    trace: TraceOptions = field(default_factory=TraceOptions)
    angles: int = 60
    assembly_budget: int = 16
    max_swept_rotors: int = 4
    random_starts: int = 12
    max_components: int = 32
    seed: int = 0
    #: Try the closed form of :mod:`engine.space.dyads` first (planar dyad chains away from critical
    #: lengths), and derive 3D hinged rotor chains from their cells (:mod:`engine.space.
    #: hinge_chain`); False always runs the general tracer and the homotopy (the tests
    #: cross-check them).
    closed_form: bool = True
    #: :func:`find_critical_points` of planar dyad chains from the closed-form candidates of
    #: :func:`engine.space.dyads.critical_candidates` (no tracing), where they are beyond doubt
    #: (critical points are in one canonical order whichever path finds them; the report then
    #: has no seeds or traced curves). Needs ``closed_form`` too; False always traces.
    critical_closed_form: bool = True
    #: With ``critical_closed_form``, where the closed form certifies that there is no critical
    #: point, take the near misses from its walks instead of tracing the curves (several times
    #: faster; it may miss one of a mirror pair of closest approaches, which seeds of a
    #: critical-value slice do not need; False: the general search's near misses).
    near_misses_closed_form: bool = False
    #: Largest path count of the homotopy that proves completeness
    #: (:mod:`engine.space.witnesses`); 0 skips it (the answer is then at best ``searched``,
    #: unless a closed form or the chain rules derive it).
    homotopy_paths_max: int = PATHS_MAX
    #: Budget of values (points x vertices) of the traced curves and segments an answer carries
    #: (:func:`engine.model.budget.answer_values`: what can be mapped and serialised in the
    #: time left after the deadline); the search stops for size there (reason ``budget``,
    #: ``answer_size_reached``). None: no budget.
    max_values: int | None = None


@dataclass(frozen=True)
class Segment:
    """A branch of the configuration space from one critical point to another (or back).

    ``start``/``end`` index critical points; ``start_ray``/``end_ray`` number the rays as in the
    second-order tangents (``+t0, -t0, +t1, -t1`` = 0..3), -1 where not a branch point.
    """

    start: int
    start_ray: int
    end: int
    end_ray: int
    points: np.ndarray


@dataclass(frozen=True)
class Component:
    """A connected component: its walk (n, M); closed walks repeat the first point at the end."""

    points: np.ndarray
    closed: bool
    through_start: bool
    critical_points: list[int]
    segments: list[int]


@dataclass(frozen=True)
class SpaceResult:
    """Outcome of :func:`explore`."""

    components: list[Component]
    critical_points: list[CriticalPoint]
    segments: list[Segment]
    near_misses: list[NearMiss]
    search: SearchReport
    degenerate: bool


@dataclass(frozen=True)
class CriticalSearch:
    """Outcome of :func:`find_critical_points`: :class:`SpaceResult` without the components
    and segments."""

    critical_points: list[CriticalPoint]
    near_misses: list[NearMiss]
    search: SearchReport
    degenerate: bool


def rays(cp: CriticalPoint) -> np.ndarray:
    """The four rays ``+t0, -t0, +t1, -t1`` (4, M) of a branch point."""
    t = cp.analysis.tangents
    return np.array([t[0], -t[0], t[1], -t[1]])


def require_one_dof(linkage: Linkage, cons: Constraints) -> None:
    if cons.n_free - cons.n_constraints != 1 or not linkage.anything_fixed:
        raise InvalidLinkage(
            "tracing needs one degree of freedom (M - E = 1 with something fixed); this linkage "
            f"has M = {cons.n_free}, E = {cons.n_constraints}"
            + ("" if linkage.anything_fixed else " and nothing fixed"),
            loc=("bars",),
        )
