"""The whole configuration space of a one-degree-of-freedom linkage.

1. **Seeds** (:mod:`engine.space.assembly`): every assembly at swept rotor angles, random
   projections.
2. **Curves**: from every seed that is not on a curve already traced, trace until the curve
   closes (:func:`engine.space.trace.trace_curve`).
3. **Critical points**: candidates where the augmented determinant changes sign along a curve,
   at deep minima of ``|det|`` along it, and from seeded multistart; each refined on the
   augmented system (:mod:`engine.local.critical`), deduplicated and classified to second order.
   Points of a non-isolated critical set are merged into one degenerate entry per stress
   support: they are never counted.
4. **Segments** (critical lengths): from every branch point along each of its four rays, trace
   until the next critical point. Components are the connected pieces of the graph of critical
   points and segments (walked as an Eulerian circuit, so consecutive points stay within the
   step bound), plus the closed curves that meet no critical point.

Planar dyad chains (a rotor and circle-circle dyads) first try the closed form of
:mod:`engine.space.dyads`: every component sampled in one vectorised pass, with a certificate
that no critical point exists; it declines (and the steps above run) at or near critical lengths.
With ``SpaceOptions.critical_closed_form`` (default), :func:`find_critical_points` of such a chain
refines closed-form candidates instead of tracing (:func:`engine.space.dyads.critical_candidates`:
wherever that certificate is in doubt) and answers only when every candidate refines to a
critical point and none is degenerate; otherwise the steps above run.

3D hinged rotor chains (:mod:`engine.space.hinge_chain`) are derived from their cells
(:mod:`.hinge`): where no cell turns, ``2^(n-1)`` components sampled in closed form; otherwise
every critical point from the runs of cell folds and a seed on every component (the fibre over
``theta_0`` and the folds), traced from those seeds alone.

Modules: :mod:`.results` (options and answers), :mod:`.explorer` (seeds and curves),
:mod:`.critical_search` (critical points along the curves), :mod:`.segments` (segments and
components), :mod:`.closed_form` (the dyad-chain path), :mod:`.hinge` (the hinged-chain
path), :mod:`.search` (the entry points :func:`explore` and :func:`find_critical_points`);
kinematics along the walks (rotor angles, windings) in :mod:`engine.space.kinematics`.
"""

from engine.space.configuration_space.closed_form import NO_CANDIDATE, closed_form_critical
from engine.space.configuration_space.explorer import SPARSE_SEED_RIGIDITY_MIN_FREE, Explorer
from engine.space.configuration_space.results import (
    Component,
    CriticalSearch,
    Segment,
    SpaceOptions,
    SpaceResult,
    rays,
)
from engine.space.configuration_space.search import explore, find_critical_points
from engine.space.kinematics import positions_along, rotor_angles, winding

#: The names of the single module this package was split from (tests and benchmarks use them).
_Explorer = Explorer
_closed_form_critical = closed_form_critical

__all__ = [
    "NO_CANDIDATE",
    "SPARSE_SEED_RIGIDITY_MIN_FREE",
    "Component",
    "CriticalSearch",
    "Explorer",
    "Segment",
    "SpaceOptions",
    "SpaceResult",
    "explore",
    "find_critical_points",
    "positions_along",
    "rays",
    "rotor_angles",
    "winding",
]
